// A CLI source that breaks the rule (cli.front_door_only_catches): an
// internal header that the package does not install.
#include "xgauge/core/error.h"
#include "xgauge/xgauge.h"
