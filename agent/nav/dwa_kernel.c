/* The DWA's per-sample arithmetic (rollouts, clearance, cost) in C: issue 17, the LTL agents'
 * step is on the fleet's latency path and its numpy calls on 126 x 13 arrays cost more than
 * their arithmetic.
 *
 * It performs dwa.py's floating-point operations (the plain array form that
 * tests/nav/test_nav_dwa_reference.py checks) in the same order, compiled without fused
 * multiply-adds or builtin rewrites (_dwa_build.py), so where numpy's sin, cos and exp are
 * libm's (x86-64 without AVX-512) the results are equal to the last bit
 * (tests/nav/test_nav_dwa_native.py). Unlike the Python form it never indexes outside the grid:
 * a point off the grid (or not a number) reads clearance -res. */

#define _GNU_SOURCE  /* sincos: glibc computes it with sin's and cos's code, the same values */
#include <math.h>

#include "dwa_kernel.h"

/* The grid's clearance at (x, y): grid.py's OccupancyGrid.clearance_xy. */
static double clearance_at(const tl_dwa_cycle *c, const double *clearance, double x, double y)
{
    if (!(x >= c->ox && x < c->ox + (double)c->nx * c->res
          && y >= c->oy && y < c->oy + (double)c->ny * c->res))
        return -c->res;
    double fx = floor((x - c->ox) / c->res);
    double fy = floor((y - c->oy) / c->res);
    long ix = fx >= 0.0 ? (fx <= (double)(c->nx - 1) ? (long)fx : c->nx - 1) : 0;
    long iy = fy >= 0.0 ? (fy <= (double)(c->ny - 1) ? (long)fy : c->ny - 1) : 0;
    return clearance[iy * (long)c->nx + ix];
}

/* Distance from (x, y) to a polyline of n vertices: polyline.py's distance_to_polyline_xy. */
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
        double len2 = abx * abx + aby * aby;
        if (len2 < 1e-12)
            len2 = 1e-12;
        double apx = x - ax, apy = y - ay;
        double s = apx * abx;
        s += apy * aby;
        s /= len2;
        if (s < 0.0)
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

/* costmap_2d's inflation cost of a clearance d: dwa.py's inflation_cost. */
static double inflation_cost(const tl_dwa_cycle *c, double d)
{
    if (d < c->robot_radius)
        return 253.0;
    if (!(d <= c->inflation_radius))
        return 0.0;
    double excess = d - c->robot_radius;
    if (excess < 0.0)
        excess = 0.0;
    return 252.0 * exp(-c->cost_scaling_factor * excess);
}

void tl_dwa_score(const tl_dwa_cycle *c, int n_samples, const double *v, const double *omega,
                  int n_times, const double *times, const double *clearance,
                  int n_discs, const double *discs, int n_ahead, const double *ahead,
                  int n_extended, const double *extended,
                  double *x, double *y, double *min_clearance, double *cost)
{
    const double sin0 = sin(c->th0), cos0 = cos(c->th0);
    const double current_cost = inflation_cost(c, c->current);
    for (int i = 0; i < n_samples; i++) {
        const double vi = v[i], wi = omega[i];
        const int turning = fabs(wi) > 1e-9;
        const double radius = vi / (turning ? wi : 1.0);
        double *xi = x + (long)i * n_times, *yi = y + (long)i * n_times;
        double least = 0.0, cos_end = 1.0, sin_end = 0.0;
        for (int k = 0; k < n_times; k++) {
            const double t = times[k];
            double theta = wi * t;
            theta += c->th0;
            double sin_t, cos_t;
            sincos(theta, &sin_t, &cos_t);
            if (turning) {
                xi[k] = (sin_t - sin0) * radius + c->px;
                yi[k] = c->py - (cos_t - cos0) * radius;
            } else {
                const double vt = vi * t;
                xi[k] = c->px + vt * cos0;
                yi[k] = c->py + vt * sin0;
            }
            double d = clearance_at(c, clearance, xi[k], yi[k]);
            for (int j = 0; j < n_discs; j++) {
                const double *disc = discs + 5 * j;
                double dx = xi[k] - (disc[0] + t * disc[2]);
                double dy = yi[k] - (disc[1] + t * disc[3]);
                dx *= dx;
                dy *= dy;
                dx += dy;
                /* Far enough that sqrt(dx) - r exceeds d with a margin far above rounding:
                 * the minimum cannot change, so the square root is not taken. */
                const double reach = d + disc[4];
                if (reach > 1e-3 && dx > reach * reach * (1.0 + 1e-6))
                    continue;
                double gap = sqrt(dx) - disc[4];
                if (gap < d)
                    d = gap;
            }
            if (k == 0 || d < least)
                least = d;
            cos_end = cos_t;
            sin_end = sin_t;
        }
        min_clearance[i] = least;

        const double end_x = xi[n_times - 1], end_y = yi[n_times - 1];
        double total = distance_to_polyline(end_x, end_y, n_ahead, ahead);
        total *= c->path_distance_bias;
        double dx = end_x - c->carrot_x, dy = end_y - c->carrot_y;
        total += c->goal_distance_bias * sqrt(dx * dx + dy * dy);
        const double front_x = end_x + c->forward_point_distance * cos_end;
        const double front_y = end_y + c->forward_point_distance * sin_end;
        total += c->path_distance_bias
                 * distance_to_polyline(front_x, front_y, n_extended, extended);
        dx = front_x - c->front_carrot_x;
        dy = front_y - c->front_carrot_y;
        total += c->goal_distance_bias * sqrt(dx * dx + dy * dy);
        double worst = inflation_cost(c, least);
        if (current_cost > worst)
            worst = current_cost;
        total += c->occdist_scale * worst;
        total += c->speed_bias * (c->max_vel_x - vi) / c->max_vel_x;
        cost[i] = total;
    }
}
