// The replay backend on generated inputs.
#include <gtest/gtest.h>
