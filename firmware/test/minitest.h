// A minimal test runner: TEST(name) { CHECK(...); } and a main that runs every
// test and prints "N passed, M failed". Host-only (uses stdio).
#pragma once

#include <math.h>
#include <stdio.h>

namespace minitest {

using TestFn = void (*)();

struct TestCase {
  const char* name;
  TestFn fn;
};

constexpr int kMaxTests = 256;
inline TestCase g_tests[kMaxTests];
inline int g_test_count = 0;
inline int g_failures_in_test = 0;
inline long g_checks = 0;

inline bool add(const char* name, TestFn fn) {
  if (g_test_count < kMaxTests) g_tests[g_test_count++] = {name, fn};
  return true;
}

inline void fail(const char* file, int line, const char* what) {
  if (g_failures_in_test < 10) fprintf(stderr, "  %s:%d: FAILED: %s\n", file, line, what);
  ++g_failures_in_test;
}

inline int run_all() {
  int passed = 0;
  int failed = 0;
  for (int i = 0; i < g_test_count; ++i) {
    g_failures_in_test = 0;
    g_tests[i].fn();
    if (g_failures_in_test == 0) {
      ++passed;
    } else {
      ++failed;
      fprintf(stderr, "FAIL %s (%d failed checks)\n", g_tests[i].name, g_failures_in_test);
    }
  }
  printf("%ld checks\n", g_checks);
  printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}

}  // namespace minitest

#define MT_CAT2(a, b) a##b
#define MT_CAT(a, b) MT_CAT2(a, b)

#define TEST(name)                                                         \
  static void MT_CAT(test_, name)();                                       \
  static const bool MT_CAT(registered_, name) =                            \
      minitest::add(#name, &MT_CAT(test_, name));                          \
  static void MT_CAT(test_, name)()

#define CHECK(cond)                                                        \
  do {                                                                     \
    ++minitest::g_checks;                                                  \
    if (!(cond)) minitest::fail(__FILE__, __LINE__, #cond);                \
  } while (0)

#define CHECK_EQ(a, b)                                                     \
  do {                                                                     \
    ++minitest::g_checks;                                                  \
    const long long mt_a = static_cast<long long>(a);                      \
    const long long mt_b = static_cast<long long>(b);                      \
    if (mt_a != mt_b) {                                                    \
      char mt_msg[256];                                                    \
      snprintf(mt_msg, sizeof mt_msg, "%s == %s (%lld vs %lld)", #a, #b,   \
               mt_a, mt_b);                                                \
      minitest::fail(__FILE__, __LINE__, mt_msg);                          \
    }                                                                      \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                              \
  do {                                                                     \
    ++minitest::g_checks;                                                  \
    const double mt_a = static_cast<double>(a);                            \
    const double mt_b = static_cast<double>(b);                            \
    if (!(fabs(mt_a - mt_b) <= static_cast<double>(tol))) {                \
      char mt_msg[256];                                                    \
      snprintf(mt_msg, sizeof mt_msg, "%s ~= %s (%.9f vs %.9f)", #a, #b,   \
               mt_a, mt_b);                                                \
      minitest::fail(__FILE__, __LINE__, mt_msg);                          \
    }                                                                      \
  } while (0)

// Like CHECK_NEAR, with a context string printed on failure.
#define CHECK_NEAR_CTX(a, b, tol, ctx)                                     \
  do {                                                                     \
    ++minitest::g_checks;                                                  \
    const double mt_a = static_cast<double>(a);                            \
    const double mt_b = static_cast<double>(b);                            \
    if (!(fabs(mt_a - mt_b) <= static_cast<double>(tol))) {                \
      char mt_msg[512];                                                    \
      snprintf(mt_msg, sizeof mt_msg, "%s: %.9f vs %.9f", (ctx), mt_a,     \
               mt_b);                                                      \
      minitest::fail(__FILE__, __LINE__, mt_msg);                          \
    }                                                                      \
  } while (0)
