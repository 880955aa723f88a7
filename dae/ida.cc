#include "dae/ida.h"
