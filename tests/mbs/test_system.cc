// Placeholder: the system tests follow.
#include <gtest/gtest.h>
