#include "dae/integrator.h"
