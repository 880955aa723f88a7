#include "mbs/system.h"
