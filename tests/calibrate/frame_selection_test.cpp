// omnipose-calibrate --max-frames: at most N of M frames, spread evenly by position, first
// and last included, and the message that says so.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "omnipose/calibrate/frame_selection.hpp"

namespace omnipose::calibrate {
namespace {

using Indices = std::vector<std::size_t>;

TEST(SelectEvenly, KeepsAllWhenThereAreNoMoreThanN) {
  EXPECT_EQ(selectEvenly(5, 60), (Indices{0, 1, 2, 3, 4}));
  EXPECT_EQ(selectEvenly(60, 60).size(), 60u);
  EXPECT_EQ(selectEvenly(60, 60).back(), 59u);
  EXPECT_EQ(selectEvenly(1, 60), (Indices{0}));
  EXPECT_TRUE(selectEvenly(0, 60).empty());
  EXPECT_TRUE(selectEvenly(10, 0).empty());
}

TEST(SelectEvenly, SmallCasesAreExact) {
  EXPECT_EQ(selectEvenly(10, 2), (Indices{0, 9}));
  EXPECT_EQ(selectEvenly(10, 3), (Indices{0, 5, 9}));  // 4.5 rounds away from zero
  EXPECT_EQ(selectEvenly(21, 3), (Indices{0, 10, 20}));
  EXPECT_EQ(selectEvenly(21, 5), (Indices{0, 5, 10, 15, 20}));
  EXPECT_EQ(selectEvenly(7, 1), (Indices{0}));
}

TEST(SelectEvenly, NOfMIsEvenlySpreadWithFirstAndLast) {
  for (const std::size_t m : {2u, 3u, 61u, 100u, 997u, 1000u, 100000u}) {
    for (const std::size_t n : {2u, 3u, 7u, 60u, 500u}) {
      SCOPED_TRACE("M = " + std::to_string(m) + ", N = " + std::to_string(n));
      const Indices idx = selectEvenly(m, n);
      const std::size_t want = std::min(m, n);
      ASSERT_EQ(idx.size(), want);
      EXPECT_EQ(idx.front(), 0u);
      EXPECT_EQ(idx.back(), m - 1);
      const double step = static_cast<double>(m - 1) / static_cast<double>(want - 1);
      for (std::size_t j = 0; j < idx.size(); ++j) {
        // Each index is the nearest to its ideal position ...
        EXPECT_LE(std::abs(static_cast<double>(idx[j]) - j * step), 0.5 + 1e-9) << "j = " << j;
        // ... and they are distinct and ascending, gaps differing by at most one frame.
        if (j > 0) {
          EXPECT_GT(idx[j], idx[j - 1]);
          const std::size_t gap = idx[j] - idx[j - 1];
          EXPECT_GE(gap, static_cast<std::size_t>(std::floor(step)));
          EXPECT_LE(gap, static_cast<std::size_t>(std::ceil(step)));
        }
      }
    }
  }
}

TEST(SelectionMessage, SaysHowManyOfHowManyAndTheStep) {
  EXPECT_EQ(selectionMessage(1000, 60), "using 60 of 1000 frames, every 16.9th (first and last included)");
  EXPECT_EQ(selectionMessage(21, 3), "using 3 of 21 frames, every 10.0th (first and last included)");
  EXPECT_EQ(selectionMessage(10, 10), "using all 10 frames");
  EXPECT_EQ(selectionMessage(1, 1), "using the 1 frame");
  EXPECT_EQ(selectionMessage(7, 1), "using 1 of 7 frames (the first)");
}

}  // namespace
}  // namespace omnipose::calibrate
