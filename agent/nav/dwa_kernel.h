/* The DWA's per-sample arithmetic in C (agent/nav/dwa_kernel.c), parsed by cffi's cdef as well
 * (no guards or other directives). Units: m, rad, s. */

/* What one cycle's samples are scored against (dwa.py's dwa_control computes it in Python). */
typedef struct {
    double px, py, th0;              /* the robot's pose */
    double ox, oy, res;              /* the grid's origin [m] and cell size [m] */
    int nx, ny;                      /* the grid's columns and rows */
    double carrot_x, carrot_y;       /* look-ahead point on the remaining path */
    double front_carrot_x, front_carrot_y;  /* the same on the path extended past its end */
    double forward_point_distance, path_distance_bias, goal_distance_bias;
    double occdist_scale, speed_bias, max_vel_x;
    double robot_radius, inflation_radius, cost_scaling_factor;
    double current;                  /* clearance at the pose itself, other robots included */
} tl_dwa_cycle;

/* Steps 2-4 of the module docstring of dwa.py for n_samples samples (v[i], omega[i]) over the
 * times[0..n_times-1]: rollouts into x, y (n_samples x n_times, row-major), each rollout's least
 * clearance into min_clearance and its cost, before admissibility, into cost (n_samples each).
 * clearance: the grid's (ny x nx) clearance layer, row-major; discs: n_discs rows of
 * (cx, cy, ux, uy, r); ahead, extended: n_ahead and n_extended path vertices (x, y). */
void tl_dwa_score(const tl_dwa_cycle *c, int n_samples, const double *v, const double *omega,
                  int n_times, const double *times, const double *clearance,
                  int n_discs, const double *discs, int n_ahead, const double *ahead,
                  int n_extended, const double *extended,
                  double *x, double *y, double *min_clearance, double *cost);
