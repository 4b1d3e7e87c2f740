// Must not compile: the store may not depend on the API above it.
#include "daemon/api/services.h"
