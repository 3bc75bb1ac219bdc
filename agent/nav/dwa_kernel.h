/* The DWA cycle in C (agent/nav/dwa_kernel.c), parsed by cffi's cdef as well (no guards or other
 * directives). Units: m, rad, s. */

/* A DwaConfig and the robot's radius (dwa.py builds one per configuration and keeps it). */
typedef struct {
    double max_vel_x, min_vel_x, max_rot_vel, acc_lim_x, acc_lim_theta, controller_period;
    int vx_samples, vtheta_samples;
    double path_distance_bias, goal_distance_bias, occdist_scale, xy_goal_tolerance;
    double forward_point_distance, inflation_radius, cost_scaling_factor, collision_margin;
    double carrot_distance, speed_bias, robot_occdist_scale, min_trans_vel, min_rot_vel;
    double robot_radius;
} tl_dwa_params;

/* The static layer: an OccupancyGrid's clearance (ny x nx, row-major) and placement. */
typedef struct {
    const double *clearance;
    int nx, ny;
    double ox, oy, res;
} tl_dwa_grid;

/* The decision: the command, its cost, the admissible samples, whether the goal was reached. */
typedef struct {
    double v, omega, cost;
    int n_valid, goal_reached;
} tl_dwa_result;

/* One cycle of dwa.py's dwa_control: pose (px, py, th0), the last command (v0, w0), the path's
 * n_path vertices (x, y), the n_others other robots (centres and velocities (x, y), radii), the
 * n_limits coupling constraints (a_v, a_omega, bound) with their largest |v| and |omega|
 * (v_cap, w_cap), the rollout times. Writes the result, the chosen rollout into trajectory
 * (n_times x 2) and, when not NULL, every sample's least clearance, cost (admissible or not)
 * and excess over the coupling limits (0 without limits; n_samples entries, at most
 * vx_samples * (vtheta_samples + 1)) with the count in *n_samples.
 * Returns 0, or -1 when memory ran out. */
int tl_dwa_control(const tl_dwa_params *p, const tl_dwa_grid *g,
                   double px, double py, double th0, double v0, double w0,
                   int n_path, const double *path,
                   int n_others, const double *centers, const double *velocities,
                   const double *radii,
                   int n_limits, const double *limits, double v_cap, double w_cap,
                   int n_times, const double *times,
                   tl_dwa_result *result, double *trajectory,
                   double *min_clearance_out, double *cost_out, double *excess_out,
                   int *n_samples);
