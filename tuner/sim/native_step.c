/* gait-tuner (ours): what runs inside every physics step that MuJoCo has no element for.
 *
 * Installed as MuJoCo's control callback (mjcb_control, called in mj_forward after the
 * kinematics, the constraint rows and the bias forces, before the actuator forces) by
 * tuner/sim/native_step.py, which compiles this file once per machine and MuJoCo version.
 * Two parts, each a no-op on a model that does not ask for it:
 *
 * 1. The servos' extended friction (tuner/servos/motor.py, BAM's m2 ... m6): on an actuator whose
 *    user numbers start with FRICTION_MAGIC, the dry-friction budget of its joint is computed from
 *    the joint's speed, the motor's torque (the position actuator's clamped force, less the
 *    back-EMF damping) and the external torque (minus the bias force), and written as the bound
 *    of the joint's friction-loss constraint row for this step (the row and its island copy) (friction_budget in motor.py is
 *    its numpy reference; the layout of the numbers is mirrored there).
 *
 * 2. The grass drag dampers' gate. It does what ContactLayer.tick (ground/layer.py) does in Python between
 * control ticks, to the bit, so that a walk on a contact-layer grass can run in MuJoCo's
 * native rollout:
 *
 *   each sole corner's two drag dampers (world x and y, actuators first + 2c and first + 2c + 1)
 *   get ctrl = 1 while the corner is under the blade tips (z < h), or with a drag depth D > 0
 *   min(1, (h - z) / D), else 0 (tuner/sim/scene.py, drag_gate);
 *
 *   the gate is held over a control tick of NSTEP physics steps and computed from the corners'
 *   heights the loop would read between ticks: the kinematics of the tick's first step for the
 *   walk's first tick, else those of the previous tick's last step (MuJoCo leaves site_xpos of a
 *   step's start behind after mj_step).
 *
 * Everything it needs is in the last BLOCK numbers of mjData.userdata (the simulator adds them to
 * the model), so the callback is a no-op on any other model, and on ours while it is not armed:
 *
 *   [ARMED] = MAGIC while a walk runs; [HEIGHT] h [m]; [DEPTH] D [m]; [NSTEP]; [STEP0] the physics
 *   step index (time / timestep) of the walk's first step; [FIRST] the first drag actuator;
 *   [NPOINT] the corners (<= MAXPOINT); then the gate in force and the gate for the next tick.
 *
 * The layout is mirrored in native_step.py; keep the two together.
 */
#include <math.h>
#include <mujoco/mujoco.h>

#define MAGIC 24061.0
#define MAXPOINT 16
enum { ARMED, HEIGHT, DEPTH, NSTEP, STEP0, FIRST, NPOINT, HEAD };
#define BLOCK (HEAD + 2 * MAXPOINT)

int gait_tuner_gate_block(void) { return BLOCK; }
double gait_tuner_gate_magic(void) { return MAGIC; }

/* ---- 1. the servos' extended friction ------------------------------------------------------ */
#define FRICTION_MAGIC 31415.0
#define FRICTION_WIDTH 15
#define MAXSERVO 64
enum { F_MAGIC, F_FLAGS, F_BASE, F_STRIBECK, F_STRIBECK_SPEED, F_ALPHA, F_LOAD, F_LOAD_S, F_LOAD_M, F_LOAD_E,
       F_LOAD_MS, F_LOAD_ES, F_LOAD_MQ, F_LOAD_EQ, F_BACK_EMF };

int gait_tuner_friction_width(void) { return FRICTION_WIDTH; }
double gait_tuner_friction_magic(void) { return FRICTION_MAGIC; }

/* the budget of one joint: motor.friction_budget's arithmetic */
double gait_tuner_friction_budget(const double* u, double speed, double motor, double external) {
  int flags = (int)u[F_FLAGS];
  int stribeck = flags & 1, load = flags & 2, directional = flags & 4, quadratic = flags & 8;
  double s = stribeck ? exp(-pow(fabs(speed / u[F_STRIBECK_SPEED]), u[F_ALPHA])) : 0.0;
  double f = u[F_BASE] + (stribeck ? u[F_STRIBECK] * s : 0.0);
  if (load) {
    if (directional) {
      f += fabs(external * u[F_LOAD_E] - motor * u[F_LOAD_M]);
      if (stribeck) f += s * fabs(external * u[F_LOAD_ES] - motor * u[F_LOAD_MS]);
      if (quadratic) {
        int opposed = (external > 0) - (external < 0) != (motor > 0) - (motor < 0);
        double quad = 0.0;
        if (fabs(external) < fabs(motor)) quad = u[F_LOAD_EQ] * external * external;
        else if (fabs(external) > fabs(motor)) quad = u[F_LOAD_MQ] * motor * motor;
        if (opposed) f += s * quad;
      }
    } else {
      double gearbox = fabs(external - motor);
      f += u[F_LOAD] * gearbox + (stribeck ? u[F_LOAD_S] * gearbox * s : 0.0);
    }
  }
  return f;
}

static void servo_friction(const mjModel* m, mjData* d) {
  int nuser = m->nuser_actuator;
  if (nuser < FRICTION_WIDTH) return;
  int dofs[MAXSERVO], acts[MAXSERVO], n = 0;
  for (int a = 0; a < m->nu && n < MAXSERVO; a++) {
    const mjtNum* u = m->actuator_user + a * nuser;
    if (u[F_MAGIC] != FRICTION_MAGIC || m->actuator_trntype[a] != mjTRN_JOINT) continue;
    dofs[n] = m->jnt_dofadr[m->actuator_trnid[2 * a]];
    acts[n] = a;
    n++;
  }
  if (!n) return;
  for (int i = 0; i < d->nefc; i++) {
    if (d->efc_type[i] != mjCNSTR_FRICTION_DOF) continue;
    int dof = d->efc_id[i];
    for (int k = 0; k < n; k++) {
      if (dofs[k] != dof) continue;
      int a = acts[k];
      const mjtNum* u = m->actuator_user + a * nuser;
      const mjtNum* g = m->actuator_gainprm + a * mjNGAIN;
      const mjtNum* b = m->actuator_biasprm + a * mjNBIAS;
      double force = g[0] * d->ctrl[a] + b[0] + b[1] * d->actuator_length[a] + b[2] * d->actuator_velocity[a];
      if (m->actuator_forcelimited[a]) {
        force = fmax(m->actuator_forcerange[2 * a], fmin(m->actuator_forcerange[2 * a + 1], force));
      }
      double speed = d->qvel[dof];
      double motor = force * m->actuator_gear[6 * a] - u[F_BACK_EMF] * speed;
      double budget = gait_tuner_friction_budget(u, speed, motor, -d->qfrc_bias[dof]);
      d->efc_frictionloss[i] = budget;
      /* the solver works on the islands' copy, made with the rows (mj_island): the bound goes there too */
      if (d->nisland > 0 && d->map_efc2iefc && d->map_efc2iefc[i] >= 0) {
        d->iefc_frictionloss[d->map_efc2iefc[i]] = budget;
      }
      break;
    }
  }
}

/* ---- 2. the grass drag gate ---------------------------------------------------------------- */

static void gate(const mjModel* m, const mjData* d, const mjtNum* u, mjtNum* out) {
  int first = (int)u[FIRST], n = (int)u[NPOINT];
  mjtNum h = u[HEIGHT], depth = u[DEPTH];
  for (int c = 0; c < n; c++) {
    int site = m->actuator_trnid[2 * (first + 2 * c)];
    mjtNum z = d->site_xpos[3 * site + 2];
    if (!(z < h)) {
      out[c] = 0.0;
    } else if (depth <= 0.0) {
      out[c] = 1.0;
    } else {
      out[c] = fmin(1.0, (h - z) / depth);
    }
  }
}

static void drag_gate(const mjModel* m, mjData* d) {
  if (m->nuserdata < BLOCK) return;
  mjtNum* u = d->userdata + (m->nuserdata - BLOCK);
  if (u[ARMED] != MAGIC) return;
  int first = (int)u[FIRST], n = (int)u[NPOINT];
  long nstep = (long)u[NSTEP];
  if (n < 0 || n > MAXPOINT || nstep < 1 || first < 0 || first + 2 * n > m->nu) return;
  mjtNum* now = u + HEAD;
  mjtNum* next = now + MAXPOINT;
  long i = lround(d->time / m->opt.timestep) - (long)u[STEP0];
  if (i < 0) return;
  long s = i % nstep;
  if (i == 0) gate(m, d, u, next);
  if (s == 0) {
    for (int c = 0; c < n; c++) now[c] = next[c];
  }
  for (int c = 0; c < n; c++) {
    d->ctrl[first + 2 * c] = now[c];
    d->ctrl[first + 2 * c + 1] = now[c];
  }
  if (s == nstep - 1) gate(m, d, u, next);
}

/* the callback: both parts */
void gait_tuner_step(const mjModel* m, mjData* d) {
  servo_friction(m, d);
  drag_gate(m, d);
}
