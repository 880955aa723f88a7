#include "mbs/kinematics.h"
