#include "mbs/spline.h"
