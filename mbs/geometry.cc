#include "mbs/geometry.h"
