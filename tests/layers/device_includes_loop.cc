// Compiles: the device layer depends on the loop below it.
#include "daemon/loop/engine.h"

int DeviceSeesTheLoop() {
  return rheo::daemon::kMaxSceneObjects;
}
