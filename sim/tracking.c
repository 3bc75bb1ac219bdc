/* The simulator's tracking law in C (sim/world.py, issue 17): what SimRobot.track does in Python,
 * the same IEEE operations in the same order, for every robot of a world in one call.
 *
 *     v' = v + sat_a((u - v) * dt / max(tau, dt)),   omega likewise      (world.py: tracking)
 *
 * Called from Chipmunk's velocity update of the world's first robot body, once per physics step
 * (5 robots at 1 kHz: 1 000 calls per sim second instead of 5 000 Python laws). Chipmunk is
 * reached through function pointers taken from pymunk's own module, so this file links against
 * nothing but libm.
 *
 * Bit-for-bit equality with the Python law (tests/sim/test_sim_tracking_native.py) rests on:
 * doubles throughout, no contraction into fused multiply-adds (-ffp-contract=off), no builtin
 * rewriting of cos/sin (-fno-builtin: GCC would merge them into one sincos call), and only
 * correctly rounded operations besides libm's cos and sin, which CPython's math.cos and
 * math.sin call too: the norm is sqrt(x*x + y*y), not hypot, whose CPython and libm versions
 * may differ in the last bit.
 *
 * tl_read_poses reads every robot's pose for a mocap frame in one call (issue 17: a fleet of 30
 * read pose by pose in Python cost ~40 us per frame from cold caches, 10 frames a period). Its
 * angle wrap is world.py's wrap_angle: atan2(sin t, cos t), and pi for -pi; CPython's math.atan2
 * calls libm's atan2 for finite arguments and gives libm's values for the zeros it handles itself.
 */
#include <math.h>

#include "tracking.h"

/* (x, y) scaled down to norm <= bound, as world.py's _limit_norm_sqrt. */
static void limit_norm(double *x, double *y, double bound)
{
    double norm = sqrt(*x * *x + *y * *y);
    if (norm <= bound)
        return;
    double scale = bound / norm;
    for (;;) {
        double xs = *x * scale, ys = *y * scale;
        if (!(sqrt(xs * xs + ys * ys) > bound))
            break;
        scale = nextafter(scale, 0.0);
    }
    *x = *x * scale;
    *y = *y * scale;
}

static void track(const tl_chipmunk *cp, tl_robot *r, double dt)
{
    if (dt != r->dt) {
        r->dt = dt;
        r->gain = dt / (dt > r->tau ? dt : r->tau);  /* Python's max(tau, dt) */
        r->dv_max = r->acc_lin * dt;
        r->dw_max = r->acc_ang * dt;
    }
    double gain = r->gain;
    tl_vect vel = cp->get_velocity(r->body);
    double vx = vel.x - r->applied[0], vy = vel.y - r->applied[1];
    double omega = cp->get_angular_velocity(r->body) - r->applied[2];
    if (r->omni) {
        double dvx = (r->target[0] - vx) * gain, dvy = (r->target[1] - vy) * gain;
        limit_norm(&dvx, &dvy, r->dv_max);
        vx = vx + dvx;
        vy = vy + dvy;
    } else {
        double angle = cp->get_angle(r->body);
        double c = cos(angle), s = sin(angle);
        double v = vx * c + vy * s;  /* forward speed; the lateral part is dropped (no slip) */
        double dv = (r->target[0] - v) * gain;
        dv = dv > -r->dv_max ? dv : -r->dv_max;
        v += dv < r->dv_max ? dv : r->dv_max;
        vx = v * c;
        vy = v * s;
    }
    double dw = (r->target[2] - omega) * gain;
    dw = dw > -r->dw_max ? dw : -r->dw_max;
    omega += dw < r->dw_max ? dw : r->dw_max;
    for (int i = 0; i < 3; i++)
        r->applied[i] = r->disturbance[i];
    tl_vect out = {vx + r->applied[0], vy + r->applied[1]};
    cp->set_velocity(r->body, out);
    cp->set_angular_velocity(r->body, omega + r->applied[2]);
}

void tl_track_all(const tl_chipmunk *cp, tl_robot *robots, int n, double dt)
{
    for (int i = 0; i < n; i++)
        track(cp, &robots[i], dt);
}

/* world.py's wrap_angle: theta [rad] wrapped to (-pi, pi]. */
static double wrap_angle(double theta)
{
    double wrapped = atan2(sin(theta), cos(theta));
    return wrapped <= -M_PI ? M_PI : wrapped;
}

void tl_read_poses(const tl_chipmunk *cp, const tl_robot *robots, int n, const double *noise,
                   double *out)
{
    for (int i = 0; i < n; i++) {
        tl_vect p = cp->get_position(robots[i].body);
        double theta = wrap_angle(cp->get_angle(robots[i].body));
        if (noise) {
            p.x = p.x + noise[3 * i];
            p.y = p.y + noise[3 * i + 1];
            theta = wrap_angle(theta + noise[3 * i + 2]);
        }
        out[3 * i] = p.x;
        out[3 * i + 1] = p.y;
        out[3 * i + 2] = theta;
    }
}
