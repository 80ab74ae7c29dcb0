// PRT_DCHECK compiled as a debug build compiles it, whatever this build's NDEBUG: test_guards.cpp
// checks that it fires here and that it is compiled out where NDEBUG is set.
#undef NDEBUG
#include "prt/error.h"

namespace prt::test {

int debugDcheckEvaluations() {
  int evaluations = 0;
  PRT_DCHECK(++evaluations > 0);
  PRT_DCHECK_LT(++evaluations, 10);
  return evaluations;
}

void debugDcheckFails(int a, int b) { PRT_DCHECK_EQ(a, b); }

}  // namespace prt::test
