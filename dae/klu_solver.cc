#include "dae/klu_solver.h"
