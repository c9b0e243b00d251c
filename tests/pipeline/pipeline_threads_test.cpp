// The per-frame result does not depend on PipelineOptions::threads: every window and every
// de-rotated row is computed by the same code on the same data whichever worker runs it.
// Compared bit for bit (memcmp of the doubles), not within a tolerance.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fftw3.h>
#include <unistd.h>

#include <cstring>

#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

/// Everything process() reports about a frame pair, plus the first pass's window motions.
struct Trace {
  std::vector<double> values;
  void add(double x) { values.push_back(x); }
  template <class M>
  void add(const Eigen::MatrixBase<M>& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) values.push_back(m.derived().data()[i]);
  }
};

Trace run(const std::vector<cv::Mat>& frames, int threads, int refine_iterations) {
  PipelineOptions options;
  options.threads = threads;
  options.refine_iterations = refine_iterations;
  Pipeline pipeline(Calibration{}, options);
  EXPECT_EQ(pipeline.threads(), threads);
  Trace t;
  for (const cv::Mat& f : frames) {
    auto m = pipeline.process(f);
    EXPECT_TRUE(m.has_value());
    if (!m || !m->has_motion) continue;
    t.add(m->estimate.omega);
    t.add(m->estimate.tau);
    t.add(m->estimate.covariance);
    t.add(m->estimate.residual_rms_px);
    t.add(static_cast<double>(m->estimate.windows_used));
    t.add(m->rotation);
    t.add(m->translation_direction);
    for (const WindowMotion& w : pipeline.lastWindows()) {
      for (double x : {w.center_u, w.du, w.dv, w.rotation, w.scale, w.confidence, w.rs_confidence})
        t.add(x);
      t.add(w.valid ? 1.0 : 0.0);
    }
  }
  return t;
}

TEST(PipelineThreads, ResultIsBitIdenticalForAnyThreadCount) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  cv::setNumThreads(1);
  synth::RenderOptions ro;
  ro.supersample = 2;
  const synth::Renderer renderer(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere),
                                 Calibration{}, ro);
  std::vector<cv::Mat> frames(4);
  for (int k = 0; k < 4; ++k)
    renderer.render(testing::relativePose(Eigen::Vector3d(0.02 * k, -0.01 * k, 0.04 * k),
                                          Eigen::Vector3d(0.05 * k, 0.0, 0.0)))
        .convertTo(frames[k], CV_8U);

  for (int refine : {0, 1}) {
    const Trace one = run(frames, 1, refine);
    ASSERT_GT(one.values.size(), 3u * 56u) << "no motion measured";
    for (int threads : {2, 3, 5}) {
      const Trace many = run(frames, threads, refine);
      ASSERT_EQ(many.values.size(), one.values.size()) << threads << " threads";
      EXPECT_EQ(std::memcmp(many.values.data(), one.values.data(),
                            one.values.size() * sizeof(double)),
                0)
          << threads << " threads, refine_iterations " << refine << ": results differ";
    }
  }
}

TEST(PipelineThreads, ALibraryStartsNoThreadsUnlessAsked) {
  EXPECT_EQ(PipelineOptions{}.threads, 1);
  Pipeline pipeline(Calibration{}, PipelineOptions{});
  EXPECT_EQ(pipeline.threads(), 1);
}

TEST(PipelineThreads, ZeroMeansAllOnlineCoresAndBadCountsAreRejected) {
  PipelineOptions options;
  options.threads = 0;
  Pipeline pipeline(Calibration{}, options);
  EXPECT_GE(pipeline.threads(), 1);
  options.threads = -1;
  EXPECT_THROW(Pipeline(Calibration{}, options), std::invalid_argument);
  options.threads = 257;
  EXPECT_THROW(Pipeline(Calibration{}, options), std::invalid_argument);
}

TEST(PipelineWisdom, WrittenOnFirstStartThenLoaded) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("omnipose_wisdom_" + std::to_string(::getpid()) + ".txt");
  std::filesystem::remove(path);
  PipelineOptions options;
  options.threads = 2;
  options.fftw_wisdom = path.string();
  {
    Pipeline first(Calibration{}, options);
    EXPECT_FALSE(first.wisdomLoaded());
  }
  ASSERT_TRUE(std::filesystem::exists(path));
  const std::string text = omnipose::testing::readText(path);
  EXPECT_THAT(text, HasSubstr("fftw")) << "not an FFTW wisdom file:\n" << text;
  {
    Pipeline second(Calibration{}, options);
    EXPECT_TRUE(second.wisdomLoaded());
  }
  std::filesystem::remove(path);
}

TEST(PipelineWisdom, AFileWithoutThePipelinesTransformsIsCompletedThenKeptAsItIs) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("omnipose_wisdom_other_" + std::to_string(::getpid()) + ".txt");
  std::filesystem::remove(path);
  // A file holding other transforms only (64-pixel windows); fftwf_forget_wisdom() makes
  // each start-up below see only what its file holds, as a fresh process would.
  fftwf_forget_wisdom();
  PipelineOptions other;
  other.threads = 1;
  other.registration.window = 64;
  other.fftw_wisdom = path.string();
  { Pipeline first(Calibration{}, other); }
  const std::string small = omnipose::testing::readText(path);
  ASSERT_FALSE(small.empty());

  // The default 110-pixel windows: the file is read, their plans are made and added to it.
  fftwf_forget_wisdom();
  PipelineOptions options;
  options.threads = 1;
  options.fftw_wisdom = path.string();
  {
    Pipeline second(Calibration{}, options);
    EXPECT_TRUE(second.wisdomLoaded());
  }
  const std::string full = omnipose::testing::readText(path);
  EXPECT_GT(full.size(), small.size()) << "the new transforms were not added to the file";

  // Everything is in the file now: a fresh start-up takes its plans from it and plans
  // nothing, so the file stays byte for byte as it was.
  fftwf_forget_wisdom();
  {
    Pipeline third(Calibration{}, options);
    EXPECT_TRUE(third.wisdomLoaded());
  }
  EXPECT_EQ(omnipose::testing::readText(path), full);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace omnipose
