#include "mbs/loader.h"
