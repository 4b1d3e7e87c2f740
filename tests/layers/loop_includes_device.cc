// Must not compile: the loop may not depend on the device layer above it.
#include "daemon/device/device_link.h"
