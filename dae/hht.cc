#include "dae/hht.h"
