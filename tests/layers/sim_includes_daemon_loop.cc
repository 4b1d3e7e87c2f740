// Must not compile: the simulation library may not depend on the daemon.
#include "daemon/loop/engine.h"
