/* The DWA cycle (agent/nav/dwa.py's dwa_control) in C: issue 17, an LTL agent's 5 Hz step is on
 * the fleet's latency path, and its process wakes from a halted vCPU, where Python runs several
 * times slower than back to back.
 *
 * It performs the numpy kernel's floating-point operations (dwa.py, checked against the plain
 * array form by tests/nav/test_nav_dwa_reference.py) in the same order, with Python's min and
 * max where Python calls them, compiled without fused multiply-adds or builtin rewrites
 * (_dwa_build.py); so where numpy's sin, cos and exp are libm's (x86-64 without AVX-512) the
 * results are equal to the last bit (tests/nav/test_nav_dwa_native.py). Unlike the numpy form
 * it never indexes outside the grid: a point off the grid (or not a number) reads -res. */

#define _GNU_SOURCE  /* sincos: glibc computes it with sin's and cos's code, the same values */
#include <math.h>
#include <stdlib.h>

#include "dwa_kernel.h"

/* Python's built-in max(a, b) and min(a, b): the first argument unless the second is greater
 * (smaller). */
static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }

/* dwa.py's velocity_window: (v_lo, v_hi, w_lo, w_hi) reachable within one period. */
static void velocity_window(const tl_dwa_params *p, double v, double w, double window[4])
{
    const double dt = p->controller_period;
    v = py_min(py_max(v, p->min_vel_x), p->max_vel_x);
    w = py_min(py_max(w, -p->max_rot_vel), p->max_rot_vel);
    window[0] = py_max(p->min_vel_x, v - p->acc_lim_x * dt);
    window[1] = py_min(p->max_vel_x, v + p->acc_lim_x * dt);
    window[2] = py_max(-p->max_rot_vel, w - p->acc_lim_theta * dt);
    window[3] = py_min(p->max_rot_vel, w + p->acc_lim_theta * dt);
}

/* dwa.py's braking_command: the velocity closest to standstill inside the window. */
static void braking(const tl_dwa_params *p, double v0, double w0, tl_dwa_result *r)
{
    double window[4];
    velocity_window(p, v0, w0, window);
    r->v = py_min(py_max(0.0, window[0]), window[1]);
    r->omega = py_min(py_max(0.0, window[2]), window[3]);
}

/* dwa.py's _linspace (np.linspace's values) into out[0..num-1]. */
static void linspace(double lo, double hi, int num, double *out)
{
    if (num == 1) {
        out[0] = lo;
        return;
    }
    const int div = num - 1;
    const double delta = hi - lo, step = delta / div;
    for (int i = 0; i < num; i++)
        out[i] = step == 0.0 ? (double)i / div * delta + lo : (double)i * step + lo;
    out[num - 1] = hi;
}

/* grid.py's clearance_xy and clearance_point. */
static double clearance_at(const tl_dwa_grid *g, double x, double y)
{
    if (!(x >= g->ox && x < g->ox + (double)g->nx * g->res
          && y >= g->oy && y < g->oy + (double)g->ny * g->res))
        return -g->res;
    double fx = floor((x - g->ox) / g->res);
    double fy = floor((y - g->oy) / g->res);
    long ix = fx >= 0.0 ? (fx <= (double)(g->nx - 1) ? (long)fx : g->nx - 1) : 0;
    long iy = fy >= 0.0 ? (fy <= (double)(g->ny - 1) ? (long)fy : g->ny - 1) : 0;
    return g->clearance[iy * (long)g->nx + ix];
}

/* polyline.py's distance_to_polyline_xy for one point. */
static double distance_to_polyline(double x, double y, int n, const double *vertices)
{
    if (n == 1) {
        double dx = x - vertices[0], dy = y - vertices[1];
        return sqrt(dx * dx + dy * dy);
    }
    double least = 0.0;
    for (int k = 0; k + 1 < n; k++) {
        double ax = vertices[2 * k], ay = vertices[2 * k + 1];
        double abx = vertices[2 * k + 2] - ax, aby = vertices[2 * k + 3] - ay;
        double len2 = py_max(abx * abx + aby * aby, 1e-12);
        double apx = x - ax, apy = y - ay;
        double s = apx * abx;
        s += apy * aby;
        s /= len2;
        if (s < 0.0)  /* np.maximum / np.minimum: a signed zero left here squares away */
            s = 0.0;
        if (s > 1.0)
            s = 1.0;
        double dx = apx - s * abx, dy = apy - s * aby;
        dx *= dx;
        dy *= dy;
        dx += dy;
        if (k == 0 || dx < least)
            least = dx;
    }
    return sqrt(least);
}

/* polyline.py's point_along_vertices. */
static void point_along(int n, const double *vertices, double distance, double point[2])
{
    point[0] = vertices[0];
    point[1] = vertices[1];
    if (n == 1 || distance <= 0.0)
        return;
    double travelled = 0.0;
    for (int k = 0; k + 1 < n; k++) {
        double ax = vertices[2 * k], ay = vertices[2 * k + 1];
        double dx = vertices[2 * k + 2] - ax, dy = vertices[2 * k + 3] - ay;
        double seg = sqrt(dx * dx + dy * dy);
        double reached = travelled + seg;
        if (distance < reached) {
            double s = (distance - travelled) / py_max(seg, 1e-12);
            point[0] = ax + s * dx;
            point[1] = ay + s * dy;
            return;
        }
        travelled = reached;
    }
    point[0] = vertices[2 * n - 2];
    point[1] = vertices[2 * n - 1];
}

/* costmap_2d's inflation cost of a clearance d: dwa.py's inflation_cost. */
static double inflation_cost(const tl_dwa_params *p, double d)
{
    if (d < p->robot_radius)
        return 253.0;
    if (!(d <= p->inflation_radius))
        return 0.0;
    double excess = d - p->robot_radius;
    if (excess < 0.0)
        excess = 0.0;
    return 252.0 * exp(-p->cost_scaling_factor * excess);
}

/* One rollout point at time t: dwa.py's _arcs_with_trig. */
struct arc {
    double px, py, th0, sin0, cos0;
};

static void rollout_point(const struct arc *a, double v, double w, double t,
                          double *x, double *y, double *cos_t, double *sin_t)
{
    double theta = w * t;
    theta += a->th0;
    sincos(theta, sin_t, cos_t);
    if (fabs(w) > 1e-9) {
        const double radius = v / w;
        *x = (*sin_t - a->sin0) * radius + a->px;
        *y = a->py - (*cos_t - a->cos0) * radius;
    } else {
        const double vt = v * t;
        *x = a->px + vt * a->cos0;
        *y = a->py + vt * a->sin0;
    }
}

int tl_dwa_control(const tl_dwa_params *p, const tl_dwa_grid *g,
                   double px, double py, double th0, double v0, double w0,
                   int n_path, const double *path,
                   int n_others, const double *centers, const double *velocities,
                   const double *radii,
                   int n_limits, const double *limits, double v_cap, double w_cap,
                   int n_times, const double *times,
                   tl_dwa_result *result, double *trajectory,
                   double *min_clearance_out, double *cost_out, double *excess_out,
                   int *n_samples)
{
    result->goal_reached = 0;
    result->n_valid = 0;
    result->cost = 0.0;
    if (n_samples)
        *n_samples = 0;
    const double dgx = path[2 * n_path - 2] - px, dgy = path[2 * n_path - 1] - py;
    if (sqrt(dgx * dgx + dgy * dgy) <= p->xy_goal_tolerance) {
        braking(p, v0, w0, result);
        result->goal_reached = 1;
        return 0;
    }

    /* 1. the samples: the window, clipped to the coupling limits' box, v-major */
    double window[4];
    velocity_window(p, v0, w0, window);
    double v_lo = window[0], v_hi = window[1], w_lo = window[2], w_hi = window[3];
    if (n_limits > 0) {
        v_hi = py_max(v_lo, py_min(v_hi, v_cap));
        const double lo = py_min(w_hi, py_max(w_lo, -w_cap));
        w_hi = py_max(w_lo, py_min(w_hi, w_cap));
        w_lo = lo;
    }
    const int nv = v_hi > v_lo ? p->vx_samples : 1;
    int nw = w_hi > w_lo ? p->vtheta_samples : 1;
    const int n = nv * (nw + 1);
    const int n_near_max = n_others > 0 ? n_others : 1;
    const int n_ext_max = n_path + 2;
    double *memory = malloc(sizeof(double) * (size_t)(nv + nw + 1 + 5 * n + 5 * n_near_max
                                                      + 4 * n_ext_max));
    if (!memory)
        return -1;
    double *vs = memory, *ws = vs + nv, *sv = ws + nw + 1, *sw = sv + n;
    double *least = sw + n, *cost = least + n, *excess = cost + n, *near = excess + n;
    double *ahead = near + 5 * n_near_max, *extended = ahead + 2 * n_ext_max;
    if (nv > 1)
        linspace(v_lo, v_hi, nv, vs);
    else
        vs[0] = v_lo;
    if (nw > 1)
        linspace(w_lo, w_hi, nw, ws);
    else
        ws[0] = w_lo;
    if (w_lo < 0.0 && 0.0 < w_hi) {
        int has_zero = 0, below = 0;
        for (int j = 0; j < nw; j++) {
            has_zero |= ws[j] == 0.0;
            below += ws[j] < 0.0;
        }
        if (!has_zero) {  /* sorted([*ws, 0.0]) */
            for (int j = nw; j > below; j--)
                ws[j] = ws[j - 1];
            ws[below] = 0.0;
            nw++;
        }
    }
    const int s_count = nv * nw;
    for (int i = 0; i < nv; i++)
        for (int j = 0; j < nw; j++) {
            sv[i * nw + j] = vs[i];
            sw[i * nw + j] = ws[j];
        }

    /* 2. the other robots that may come within inflation_radius of a rollout (_near_discs) */
    const double horizon = times[n_times - 1];
    double top = 0.0;
    for (int i = 0; i < s_count; i++)
        if (i == 0 || fabs(sv[i]) > top)
            top = fabs(sv[i]);
    const double reach = top * horizon;
    const double current_static = clearance_at(g, px, py);
    double current = current_static, current_robots = INFINITY;
    int n_near = 0;
    for (int j = 0; j < n_others; j++) {
        const double cx = centers[2 * j], cy = centers[2 * j + 1];
        const double ux = velocities[2 * j], uy = velocities[2 * j + 1], r = radii[j];
        const double ex = cx - px, ey = cy - py;
        const double bound = sqrt(ex * ex + ey * ey) - reach - sqrt(ux * ux + uy * uy) * horizon
                             - r;
        if (bound <= p->inflation_radius + 1e-6) {
            double *disc = near + 5 * n_near++;
            disc[0] = cx;
            disc[1] = cy;
            disc[2] = ux;
            disc[3] = uy;
            disc[4] = r;
        }
    }
    for (int j = 0; j < n_near; j++) {
        const double ex = near[5 * j] - px, ey = near[5 * j + 1] - py;
        const double gap = sqrt(ex * ex + ey * ey) - near[5 * j + 4];
        current = py_min(current, gap);
        current_robots = py_min(current_robots, gap);
    }
    const double required = py_min(p->robot_radius + p->collision_margin, current - 1e-6);

    /* 3. the path's targets (_path_targets): the path ahead, the look-ahead points */
    int n_ahead;
    if (n_path == 1) {
        ahead[0] = path[0];
        ahead[1] = path[1];
        n_ahead = 1;
    } else {  /* polyline.py's _project: the first closest segment */
        double best = INFINITY, qx_best = 0.0, qy_best = 0.0;
        int k_best = 0;
        for (int k = 0; k + 1 < n_path; k++) {
            const double ax = path[2 * k], ay = path[2 * k + 1];
            const double abx = path[2 * k + 2] - ax, aby = path[2 * k + 3] - ay;
            const double len2 = py_max(abx * abx + aby * aby, 1e-12);
            const double s = py_min(py_max(((px - ax) * abx + (py - ay) * aby) / len2, 0.0), 1.0);
            const double qx = ax + s * abx, qy = ay + s * aby;
            const double dx = qx - px, dy = qy - py;
            const double d2 = dx * dx + dy * dy;
            if (d2 < best) {
                best = d2;
                k_best = k;
                qx_best = qx;
                qy_best = qy;
            }
        }
        ahead[0] = qx_best;
        ahead[1] = qy_best;
        n_ahead = 1;
        for (int k = k_best + 1; k < n_path; k++) {
            ahead[2 * n_ahead] = path[2 * k];
            ahead[2 * n_ahead + 1] = path[2 * k + 1];
            n_ahead++;
        }
    }
    double carrot[2], front_carrot[2];
    point_along(n_ahead, ahead, p->carrot_distance, carrot);
    const double fpd = p->forward_point_distance;
    int n_extended = n_ahead;
    for (int k = 0; k < 2 * n_ahead; k++)
        extended[k] = ahead[k];
    {  /* dwa.py's _extend */
        const double ex = ahead[2 * n_ahead - 2], ey = ahead[2 * n_ahead - 1];
        const double bx = n_ahead >= 2 ? ahead[2 * n_ahead - 4] : px;
        const double by = n_ahead >= 2 ? ahead[2 * n_ahead - 3] : py;
        const double dx = ex - bx, dy = ey - by;
        const double norm = sqrt(dx * dx + dy * dy);
        if (!(norm < 1e-9)) {
            const double scale = fpd / norm;
            extended[2 * n_extended] = ex + dx * scale;
            extended[2 * n_extended + 1] = ey + dy * scale;
            n_extended++;
        }
    }
    point_along(n_extended, extended, p->carrot_distance + fpd, front_carrot);

    /* 4. every sample's rollout, least clearance and cost */
    const struct arc arc = {px, py, th0, sin(th0), cos(th0)};
    const double static_cost = inflation_cost(p, current_static);
    const double robots_cost = inflation_cost(p, current_robots);
    for (int i = 0; i < s_count; i++) {
        double d_least = 0.0, s_least = 0.0, r_least = INFINITY;
        double x = px, y = py, cos_t = 1.0, sin_t = 0.0;
        for (int k = 0; k < n_times; k++) {
            const double t = times[k];
            rollout_point(&arc, sv[i], sw[i], t, &x, &y, &cos_t, &sin_t);
            const double d_static = clearance_at(g, x, y);
            double d = d_static, d_robots = INFINITY;
            for (int j = 0; j < n_near; j++) {
                const double *disc = near + 5 * j;
                double dx = x - (disc[0] + t * disc[2]);
                double dy = y - (disc[1] + t * disc[3]);
                dx *= dx;
                dy *= dy;
                dx += dy;
                /* Far enough that sqrt(dx) - r exceeds both d and inflation_radius with a
                 * margin far above rounding: neither the least clearance nor the robots'
                 * inflation cost can change, so the square root is not taken. */
                const double within = py_max(d, p->inflation_radius) + disc[4];
                if (within > 1e-3 && dx > within * within * (1.0 + 1e-6))
                    continue;
                const double gap = sqrt(dx) - disc[4];
                if (gap < d)
                    d = gap;
                if (gap < d_robots)
                    d_robots = gap;
            }
            if (k == 0 || d < d_least)
                d_least = d;
            if (k == 0 || d_static < s_least)
                s_least = d_static;
            if (d_robots < r_least)
                r_least = d_robots;
        }
        least[i] = d_least;
        double total = distance_to_polyline(x, y, n_ahead, ahead);
        total *= p->path_distance_bias;
        double dx = x - carrot[0], dy = y - carrot[1];
        total += p->goal_distance_bias * sqrt(dx * dx + dy * dy);
        const double front_x = x + fpd * cos_t, front_y = y + fpd * sin_t;
        total += p->path_distance_bias
                 * distance_to_polyline(front_x, front_y, n_extended, extended);
        dx = front_x - front_carrot[0];
        dy = front_y - front_carrot[1];
        total += p->goal_distance_bias * sqrt(dx * dx + dy * dy);
        double worst = inflation_cost(p, s_least);
        if (static_cost > worst)
            worst = static_cost;
        total += p->occdist_scale * worst;
        double worst_robots = inflation_cost(p, r_least);
        if (robots_cost > worst_robots)
            worst_robots = robots_cost;
        total += p->robot_occdist_scale * worst_robots;
        total += p->speed_bias * (p->max_vel_x - sv[i]) / p->max_vel_x;
        cost[i] = total;
    }
    /* 5. admissibility (collision, then the coupling limits) and the choice */
    int any_valid = 0;
    for (int i = 0; i < s_count; i++) {
        any_valid |= least[i] >= required;
        double e = 0.0;  /* excess: max over the constraints of a|v| + b|w| - c */
        for (int c = 0; c < n_limits; c++) {
            const double *row = limits + 3 * c;
            const double ec = row[0] * fabs(sv[i]) + row[1] * fabs(sw[i]) - row[2];
            if (c == 0 || ec > e)
                e = ec;
        }
        excess[i] = e;
    }
    if (min_clearance_out && cost_out && excess_out && n_samples) {
        for (int i = 0; i < s_count; i++) {
            min_clearance_out[i] = least[i];
            cost_out[i] = cost[i];
            excess_out[i] = excess[i];
        }
        *n_samples = s_count;
    }
    int coupled = 0;
    double threshold = 1e-12;
    if (n_limits > 0 && any_valid) {
        coupled = 1;
        int any_coupled = 0;
        for (int i = 0; i < s_count; i++)
            any_coupled |= least[i] >= required && excess[i] <= 1e-12;
        if (!any_coupled) {  /* none meets them: keep the collision-free ones of least excess */
            double smallest = INFINITY;
            int first = 1;
            for (int i = 0; i < s_count; i++)
                if (least[i] >= required && (first || excess[i] < smallest)) {
                    smallest = excess[i];
                    first = 0;
                }
            threshold = smallest + 1e-12;
        }
    }
    /* 6. no standing still by choice: only the moving samples while one is admissible; under
     * coupling limits the thresholds are at most half their largest |v| and |w| */
    double min_v = p->min_trans_vel, min_w = p->min_rot_vel;
    if (n_limits > 0) {
        min_v = py_min(min_v, 0.5 * v_cap);
        min_w = py_min(min_w, 0.5 * w_cap);
    }
    int any_moving = 0;
    for (int i = 0; i < s_count; i++)
        any_moving |= least[i] >= required && (!coupled || excess[i] <= threshold)
                      && (fabs(sv[i]) >= min_v || fabs(sw[i]) >= min_w);
    int n_valid = 0, best = 0;
    for (int i = 0; i < s_count; i++) {
        const int valid = least[i] >= required && (!coupled || excess[i] <= threshold)
                          && (!any_moving || fabs(sv[i]) >= min_v || fabs(sw[i]) >= min_w);
        n_valid += valid;
        if (!valid)
            cost[i] = INFINITY;
        if (i > 0 && cost[i] < cost[best])  /* np.argmin: the first smallest */
            best = i;
    }
    if (n_valid == 0) {
        braking(p, v0, w0, result);
        result->cost = INFINITY;
        free(memory);
        return 0;
    }
    result->v = sv[best];
    result->omega = sw[best];
    result->cost = cost[best];
    result->n_valid = n_valid;
    for (int k = 0; k < n_times; k++) {
        double cos_t, sin_t;
        rollout_point(&arc, sv[best], sw[best], times[k], trajectory + 2 * k,
                      trajectory + 2 * k + 1, &cos_t, &sin_t);
    }
    free(memory);
    return 0;
}
