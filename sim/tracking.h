/* The C tracking law's interface (sim/tracking.c), parsed by cffi's cdef as well (no guards or
 * other directives). Units: m, rad, s. */

typedef struct { double x, y; } tl_vect;  /* Chipmunk's cpVect */

/* Chipmunk's body accessors, as pymunk's module exports them (cpBody * as void *). */
typedef struct {
    tl_vect (*get_velocity)(void *body);
    void (*set_velocity)(void *body, tl_vect velocity);
    double (*get_angular_velocity)(void *body);
    void (*set_angular_velocity)(void *body, double omega);
    double (*get_angle)(void *body);
    tl_vect (*get_position)(void *body);
} tl_chipmunk;

/* One robot: its body, its law's constants and its state (world.py's SimRobot). */
typedef struct {
    void *body;              /* cpBody * */
    int omni;                /* 1: (vx, vy, omega) in the world frame; 0: unicycle (v, omega) */
    double target[3];        /* the clipped command; a unicycle's (v, omega) as (v, 0, omega) */
    double disturbance[3];   /* w_i to apply from the next physics step on */
    double applied[3];       /* w_i inside the body's current velocity */
    double tau, acc_lin, acc_ang;   /* [s], [m/s^2], [rad/s^2] */
    double dt, gain, dv_max, dw_max;  /* cached per physics step dt; dt = NaN: not yet */
} tl_robot;

void tl_track_all(const tl_chipmunk *cp, tl_robot *robots, int n, double dt);

/* Every robot's pose, as World.poses (noise NULL) or World.mocap_poses (noise: n rows of
 * (nx, ny, ntheta)) reads it: out[3i..3i+2] = (x, y, theta wrapped to (-pi, pi]). */
void tl_read_poses(const tl_chipmunk *cp, const tl_robot *robots, int n, const double *noise,
                   double *out);
