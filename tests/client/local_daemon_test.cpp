// LocalDaemon's CPU placement helpers: the taskset-style lists service_bench takes for
// --daemon-cpus / --client-cpus, and pinning the calling thread.
#include <sched.h>

#include <thread>

#include <gtest/gtest.h>

#include "clients/client/local_daemon.h"

namespace lightlink::client {
namespace {

TEST(CpuList, ParsesRangesAndSingles) {
  auto a = parseCpuList("0-1");
  ASSERT_TRUE(a) << a.status().toString();
  EXPECT_EQ(*a, (std::vector<int>{0, 1}));
  auto b = parseCpuList("4-6,0,2,5");
  ASSERT_TRUE(b) << b.status().toString();
  EXPECT_EQ(*b, (std::vector<int>{0, 2, 4, 5, 6})) << "sorted, duplicates dropped";
  auto c = parseCpuList("7");
  ASSERT_TRUE(c);
  EXPECT_EQ(*c, (std::vector<int>{7}));
}

TEST(CpuList, RejectsMalformedListsNamingThePart) {
  for (const char* bad : {"", "a", "1-", "-1", "3-1", "0,,1", "1.5", "99999999"}) {
    auto r = parseCpuList(bad);
    ASSERT_FALSE(r) << "'" << bad << "' was accepted";
    EXPECT_EQ(r.status().code(), Code::kInvalidInput);
    EXPECT_NE(r.status().message().find("cpu list"), std::string::npos) << r.status().message();
  }
}

TEST(CpuList, PinningRestrictsTheThreadAndItsChildren) {
  cpu_set_t before;
  ASSERT_EQ(::sched_getaffinity(0, sizeof(before), &before), 0);
  int first = -1;
  for (int c = 0; c < CPU_SETSIZE && first < 0; ++c)
    if (CPU_ISSET(c, &before)) first = c;
  ASSERT_GE(first, 0);
  // On a thread of its own, so the test process keeps its CPUs.
  std::thread([&] {
    ASSERT_TRUE(pinCurrentThread({first}));
    std::thread([&] {
      cpu_set_t now;
      ASSERT_EQ(::sched_getaffinity(0, sizeof(now), &now), 0);
      EXPECT_EQ(CPU_COUNT(&now), 1);
      EXPECT_TRUE(CPU_ISSET(first, &now));
    }).join();
  }).join();
  if (!CPU_ISSET(CPU_SETSIZE - 1, &before)) {
    EXPECT_FALSE(pinCurrentThread({CPU_SETSIZE - 1})) << "pinning to a CPU this process may not use must fail";
  }
}

}  // namespace
}  // namespace lightlink::client
