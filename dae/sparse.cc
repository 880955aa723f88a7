#include "dae/sparse.h"
