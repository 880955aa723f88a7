#include "dae/consistent.h"
