// Prints how long a test took, wall clock and process CPU time, when it goes out of scope, so
// CI logs show where the suite's time goes. CPU time divided by the core count estimates the
// wall time on an idle machine of that size. Never an assertion: timings are not test
// results (DESIGN.md).
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>

namespace pc::test {

class ScopedTestTimer {
 public:
  ScopedTestTimer() : wall0_(std::chrono::steady_clock::now()), cpu0_(std::clock()) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    if (info) name_ = std::string(info->test_suite_name()) + "." + info->name();
  }
  ~ScopedTestTimer() {
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
    const double cpu = double(std::clock() - cpu0_) / CLOCKS_PER_SEC;
    std::printf("[time] %s: %.2f s wall, %.2f s cpu\n", name_.c_str(), wall, cpu);
  }
  ScopedTestTimer(const ScopedTestTimer&) = delete;
  ScopedTestTimer& operator=(const ScopedTestTimer&) = delete;

 private:
  std::string name_ = "test";
  std::chrono::steady_clock::time_point wall0_;
  std::clock_t cpu0_;
};

}  // namespace pc::test
