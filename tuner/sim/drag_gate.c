/* gait-tuner (ours): the grass drag dampers' gate, run by MuJoCo inside every physics step.
 *
 * Installed as MuJoCo's control callback (mjcb_control, called in mj_forward after the
 * kinematics and before the actuator forces) by tuner/sim/native_gate.py, which compiles this
 * file once per machine and MuJoCo version. It does what Simulator._ground_tick does in Python
 * between control ticks, to the bit, so that a walk on a contact-layer grass can run in MuJoCo's
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
 * The layout is mirrored in native_gate.py; keep the two together.
 */
#include <math.h>
#include <mujoco/mujoco.h>

#define MAGIC 24061.0
#define MAXPOINT 16
enum { ARMED, HEIGHT, DEPTH, NSTEP, STEP0, FIRST, NPOINT, HEAD };
#define BLOCK (HEAD + 2 * MAXPOINT)

int gait_tuner_gate_block(void) { return BLOCK; }
double gait_tuner_gate_magic(void) { return MAGIC; }

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

void gait_tuner_drag_gate(const mjModel* m, mjData* d) {
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
