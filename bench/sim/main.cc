// sim_bench: measured, not asserted.
//   sim_bench speed [max_tets]       median wall time of one 1 ms tick vs mesh size
//   sim_bench precision [svg_path]   work-precision: CPU time per simulated second vs error
//   sim_bench bullet                 btSoftBody on the same tets and dt, vs the same reference
//   sim_bench kernels [tets] [sample]  time of each force kernel and Jacobian product (on a box,
//                                    or on samples/SAMPLE.json meshed at about that size)
//   sim_bench cg                     implicit integrator: CG tolerance vs error and cost
//   sim_bench precond [max_tets]     CG preconditioners on one tick's system
//   sim_bench sketched [sample] [max_tets]   a sketched sample at ~5k/20k/100k tets, drop and
//                                    press, tick median and tails beside Bullet's step
//   sim_bench precision-sizes [sample] [max_tets] [svg_prefix]  work-precision of each
//                                    integrator and Bullet at ~5k/20k/100k tets, an SVG per size
//   sim_bench budget [sample] [max_tets]  the implicit step's solver settings (preconditioner,
//                                    kept blocks, iteration cap, tolerance): tick median and tail
//                                    beside the error against a fine-tick reference, per size
//   sim_bench trace [sample] [max_tets] [drop|press] [preset=NAME] [name=value...]
//                                    per 10 ms of a precision-sizes scene (BDF2, 1 ms): CPU, CG
//                                    iterations, the system's elements, floor contact
//   sim_bench multirate [sample] [max_tets]  a press through the renderer: the multi-rate scheme
//                                    (patch every tick, whole every N) against the full solve
// One thread throughout (the library has none).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "bench.h"

using namespace sim_bench;

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "speed";
  if (mode == "speed") return Speed(argc > 2 ? std::atoi(argv[2]) : 100000);
  if (mode == "cg") return CgSweep();
  if (mode == "params") return ParameterChange();
  if (mode == "kernels")
    return Kernels(argc > 2 ? std::atoi(argv[2]) : 5000, argc > 3 ? argv[3] : "");
  if (mode == "precond") return Preconditioners(argc > 2 ? std::atoi(argv[2]) : 100000);
  if (mode == "sketched")
    return Sketched(argc > 2 ? argv[2] : "bean", argc > 3 ? std::atoi(argv[3]) : 100000);
  if (mode == "budget")
    return Budget(argc > 2 ? argv[2] : "bean", argc > 3 ? std::atoi(argv[3]) : 20000);
  if (mode == "multirate")
    return MultiRate(argc > 2 ? argv[2] : "bean", argc > 3 ? std::atoi(argv[3]) : 100000);
  if (mode == "precision-sizes")
    return PrecisionSizes(argc > 2 ? argv[2] : "bean", argc > 3 ? std::atoi(argv[3]) : 100000,
                          argc > 4 ? argv[4] : "sim_work_precision");
  if (mode == "trace")
    return Trace(argc > 2 ? argv[2] : "bean", argc > 3 ? std::atoi(argv[3]) : 20000,
                 argc > 4 ? argv[4] : "drop",
                 std::span<char* const>(argv + std::min(argc, 5), argv + argc));
  if (mode == "precision") return Precision(argc > 2 ? argv[2] : "sim_work_precision.svg");
#ifdef RHEO_HAVE_BULLET
  if (mode == "bullet") return Bullet();
  if (mode == "bullet-check") return BulletCheck();
#else
  if (mode == "bullet") {
    std::fprintf(stderr, "sim_bench: built without Bullet (libbullet-dev)\n");
    return 1;
  }
#endif
  std::fprintf(stderr,
               "usage: sim_bench speed [max_tets] | kernels [tets] [sample] | precond [max_tets] | "
               "precision [svg] | "
               "cg | params | bullet | sketched [sample] [max_tets] | budget [sample] [max_tets] | "
               "multirate [sample] [max_tets] | "
               "precision-sizes [sample] [max_tets] [svg_prefix] | trace [sample] [max_tets] "
               "[drop|press] [preset=NAME] [name=value...]\n");
  return 1;
}
