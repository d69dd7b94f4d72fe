/* A C host of the plugin (docs/mujoco-plugin.md, "From C"): loads libpneuflex_mujoco.so, compiles an MJCF,
 * steps it with a constant command and prints the cylinder's force and chamber pressures, or the load error.
 * Built and run by crates/python/tests/test_mujoco_plugin.py against the wheel's headers and libmujoco:
 *   cc -I$MJ/include host.c -o host -L$MJ -l:libmujoco.so.4.0.0 -Wl,-rpath,$MJ
 *   ./host PLUGIN.so MODEL.xml STEPS CTRL      exit 0 (printed "ok ..."), 2 (load error printed), 1 (usage) */
#include <stdio.h>
#include <stdlib.h>
#include <mujoco/mujoco.h>

int main(int argc, char** argv) {
  if (argc != 5) {
    fprintf(stderr, "usage: %s PLUGIN.so MODEL.xml STEPS CTRL\n", argv[0]);
    return 1;
  }
  mj_loadPluginLibrary(argv[1]);
  char error[2048] = "";
  mjModel* m = mj_loadXML(argv[2], NULL, error, sizeof error);
  if (!m) {
    printf("load error: %s\n", error);
    return 2;
  }
  mjData* d = mj_makeData(m);
  long steps = strtol(argv[3], NULL, 10);
  for (long i = 0; i < steps; i++) {
    d->ctrl[0] = strtod(argv[4], NULL);
    mj_step(m, d);
  }
  /* The first instance's first cylinder: p_a, p_b are its first two numbers of plugin_state. */
  const mjtNum* s = d->plugin_state + m->plugin_stateadr[0];
  printf("ok t=%.17g x=%.17g force=%.17g p_a=%.17g p_b=%.17g\n", d->time, d->qpos[0], d->actuator_force[0],
         s[0], s[1]);
  mj_deleteData(d);
  mj_deleteModel(m);
  return 0;
}
