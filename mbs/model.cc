#include "mbs/model.h"
