#include "mbs/expression.h"
