// The allocation counter counts what the allocation tests rely on: every member of the
// malloc family, every operator new, in this thread and (process scope) in other threads;
// a thread-scope counter ignores other threads; ExcludedScope moves allocations apart.
#include "allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <malloc.h>

#include <cstdlib>
#include <new>
#include <thread>
#include <vector>

using ::testing::HasSubstr;

namespace omnipose::testing {
namespace {

// Keeps the compiler from eliding an allocation whose result is unused.
template <typename T>
T* keep(T* p) {
  asm volatile("" : : "g"(p) : "memory");
  return p;
}

class AllocationCounterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!AllocationCounter::available())
      GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  }
};

TEST_F(AllocationCounterTest, NothingAllocatedCountsZero) {
  AllocationCounter counter;
  int x = 0;
  keep(&x);
  EXPECT_EQ(counter.stop(), 0);
}

TEST_F(AllocationCounterTest, CountsEachMemberOfTheMallocFamilyOnce) {
  struct Case {
    const char* name;
    void* (*allocate)();
  };
  const Case cases[] = {
      {"malloc", [] { return std::malloc(64); }},
      {"calloc", [] { return std::calloc(8, 8); }},
      {"realloc(nullptr)", [] { return std::realloc(nullptr, 64); }},
      {"aligned_alloc", [] { return std::aligned_alloc(64, 128); }},
      {"memalign", [] { return memalign(64, 100); }},
      {"posix_memalign",
       [] {
         void* p = nullptr;
         return posix_memalign(&p, 64, 100) == 0 ? p : nullptr;
       }},
      {"valloc", [] { return valloc(100); }},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    AllocationCounter counter;
    void* p = keep(c.allocate());
    const std::int64_t n = counter.stop();
    ASSERT_NE(p, nullptr);
    std::free(p);
    EXPECT_EQ(n, 1);
  }
  // realloc of a block counts (it may move it).
  void* p = keep(std::malloc(16));
  AllocationCounter counter;
  p = keep(std::realloc(p, 4096));
  EXPECT_EQ(counter.stop(), 1);
  std::free(p);
}

struct alignas(64) Aligned {
  float v[16];
};

TEST_F(AllocationCounterTest, CountsEveryOperatorNew) {
  AllocationCounter counter;
  auto* a = keep(new int(3));
  auto* b = keep(new int[16]);
  auto* c = keep(new Aligned);                             // aligned operator new
  auto* d = keep(new Aligned[4]);                          // aligned operator new[]
  auto* e = keep(new (std::nothrow) int(4));               // nothrow
  auto* f = keep(static_cast<char*>(::operator new(10, std::align_val_t(128))));
  const std::int64_t n = counter.stop();
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(c) % 64, 0u);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(f) % 128, 0u);
  delete a;
  delete[] b;
  delete c;
  delete[] d;
  delete e;
  ::operator delete(f, std::align_val_t(128));
  EXPECT_EQ(n, 6);
}

TEST_F(AllocationCounterTest, ContainersCountTheirAllocations) {
  AllocationCounter counter;
  std::vector<int> v;
  for (int i = 0; i < 100; ++i) v.push_back(i);  // several reallocations
  keep(v.data());
  EXPECT_GE(counter.stop(), 2);
}

TEST_F(AllocationCounterTest, ProcessScopeCountsOtherThreadsThisThreadScopeDoesNot) {
  AllocationCounter process;
  AllocationCounter mine(AllocationCounter::Scope::kThisThread);
  std::int64_t worker_own = -1;
  std::thread worker([&] {
    AllocationCounter own(AllocationCounter::Scope::kThisThread);
    for (int i = 0; i < 10; ++i) std::free(keep(std::malloc(32)));
    delete keep(new int(1));
    worker_own = own.stop();
  });
  const std::int64_t mine_before_join = mine.count();
  worker.join();
  const std::int64_t in_process = process.stop();
  const std::int64_t in_mine = mine.stop();
  EXPECT_EQ(worker_own, 11);
  EXPECT_GE(in_process, 11) << "the worker's allocations (and std::thread's own)";
  // std::thread allocates its state on this thread; the worker's 11 are not counted here.
  EXPECT_LT(in_mine, 11);
  EXPECT_GE(in_mine, mine_before_join);
}

TEST_F(AllocationCounterTest, StopFreezesTheCountAndCountersNest) {
  AllocationCounter outer;
  std::free(keep(std::malloc(8)));
  {
    AllocationCounter inner;
    std::free(keep(std::malloc(8)));
    std::free(keep(std::malloc(8)));
    EXPECT_EQ(inner.stop(), 2);
    std::free(keep(std::malloc(8)));
    EXPECT_EQ(inner.count(), 2) << "frozen after stop()";
  }
  EXPECT_EQ(outer.stop(), 4);
}

TEST_F(AllocationCounterTest, ExcludedScopeCountsApart) {
  AllocationCounter counter;
  std::free(keep(std::malloc(8)));
  {
    AllocationCounter::ExcludedScope library_call;
    std::free(keep(std::malloc(8)));
    std::free(keep(std::malloc(8)));
  }
  counter.stop();
  EXPECT_EQ(counter.count(), 1);
  EXPECT_EQ(counter.excluded(), 2);
}

TEST_F(AllocationCounterTest, RecordsCallers) {
  AllocationCounter counter(AllocationCounter::Scope::kThisThread, /*record_callers=*/true);
  std::free(keep(std::malloc(8)));
  EXPECT_EQ(counter.stop(), 1);
  std::FILE* out = std::tmpfile();
  ASSERT_NE(out, nullptr);
  counter.printCallers(out);
  std::rewind(out);
  char line[512] = {};
  std::string text;
  while (std::fgets(line, sizeof(line), out)) text += line;
  std::fclose(out);
  EXPECT_THAT(text, HasSubstr("counted allocations by caller"));
  EXPECT_THAT(text, HasSubstr("counted allocation 0:"));
}

}  // namespace
}  // namespace omnipose::testing
