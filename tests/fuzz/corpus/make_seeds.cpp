// Writes the seed corpora of tests/fuzz/corpus/ and the crafted inputs of
// tests/fuzz/regressions/fuzz_frame_pipeline/ (the layouts are those documented at the top of
// each fuzz_*.cpp). Not part of the build; run from the repository root after changing a
// target's input layout:
//   g++ -std=c++17 -O1 tests/fuzz/corpus/make_seeds.cpp -o /tmp/make_seeds \
//     $(pkg-config --cflags --libs opencv4) && /tmp/make_seeds
// Frames are small donuts unwrapped backwards from tests/data/equirect/indoor_1024x512.jpg:
// a dark camera reflection in the centre, the scene on the ring, a grey lens body outside.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using Bytes = std::string;

namespace {

const fs::path kCorpus = "tests/fuzz/corpus";
const fs::path kRegressions = "tests/fuzz/regressions";

Bytes readFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  return Bytes(std::istreambuf_iterator<char>(in), {});
}

void writeFile(const fs::path& p, const Bytes& b) {
  fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(b.data(), static_cast<std::streamsize>(b.size()));
  if (!out) throw std::runtime_error("cannot write " + p.string());
}

Bytes encode(const std::string& ext, const cv::Mat& m, std::vector<int> params = {}) {
  std::vector<std::uint8_t> buf;
  if (!cv::imencode(ext, m, buf, params)) throw std::runtime_error("imencode " + ext);
  return Bytes(buf.begin(), buf.end());
}

Bytes raw(const cv::Mat& m) {
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  return Bytes(reinterpret_cast<const char*>(c.data), c.total() * c.elemSize());
}

Bytes u16(std::size_t n) {
  if (n > 0xffff) throw std::runtime_error("part too long for a u16 length");
  return Bytes{static_cast<char>(n & 0xff), static_cast<char>(n >> 8)};
}
Bytes u32(std::size_t n) {
  return Bytes{static_cast<char>(n & 0xff), static_cast<char>((n >> 8) & 0xff),
               static_cast<char>((n >> 16) & 0xff), static_cast<char>((n >> 24) & 0xff)};
}

/// A w x h grey donut, the scene turned by `turn_deg`; `mast` adds a still dark bar.
cv::Mat donut(const cv::Mat& pano, int w, int h, double turn_deg, bool mast = false) {
  const double cx = 0.5 * (w - 1), cy = 0.5 * (h - 1);
  const double r_out = 0.47 * std::min(w, h), r_in = 0.18 * std::min(w, h);
  cv::Mat mapx(h, w, CV_32F), mapy(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double r = std::hypot(x - cx, y - cy);
      double a = std::atan2(y - cy, x - cx) + turn_deg * CV_PI / 180.0;
      a = std::fmod(a + 4 * CV_PI, 2 * CV_PI);
      mapx.at<float>(y, x) = static_cast<float>(a / (2 * CV_PI) * (pano.cols - 1));
      // Outer edge = up: r_out -> row 0.36 H, r_in -> row 0.64 H of the equirectangular
      // photo (its textured band about the horizon, so the ring's edges are the lens's).
      const double t = (r - r_in) / (r_out - r_in);
      mapy.at<float>(y, x) = static_cast<float>((0.64 - 0.28 * t) * (pano.rows - 1));
    }
  cv::Mat out;
  cv::remap(pano, out, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double r = std::hypot(x - cx, y - cy);
      if (r < r_in) out.at<std::uint8_t>(y, x) = 12;
      else if (r > r_out) out.at<std::uint8_t>(y, x) = 4;
      else if (mast && std::abs(x - cx) < 3 && y > cy) out.at<std::uint8_t>(y, x) = 5;
    }
  return out;
}

/// A w x h mask: 255 on the disc of radius 0.47 min(w, h), 0 outside.
cv::Mat discMask(int w, int h) {
  cv::Mat m(h, w, CV_8UC1, cv::Scalar(0));
  cv::circle(m, {w / 2, h / 2}, static_cast<int>(0.47 * std::min(w, h)), cv::Scalar(255), cv::FILLED);
  return m;
}

/// A PNG whose IHDR declares w x h 8-bit grey pixels (valid CRC), with a tiny IDAT (one
/// deflate-compressed row) and IEND.
Bytes craftedPng(std::uint32_t w, std::uint32_t h) {
  const auto crc = [](const Bytes& b) {
    std::uint32_t c = 0xffffffffu;
    for (unsigned char ch : b) {
      c ^= ch;
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return c ^ 0xffffffffu;
  };
  const auto be32 = [](std::uint32_t v) {
    return Bytes{static_cast<char>(v >> 24), static_cast<char>((v >> 16) & 0xff),
                 static_cast<char>((v >> 8) & 0xff), static_cast<char>(v & 0xff)};
  };
  const auto chunk = [&](const char* type, const Bytes& body) {
    const Bytes typed = Bytes(type, 4) + body;
    return be32(static_cast<std::uint32_t>(body.size())) + typed + be32(crc(typed));
  };
  const Bytes ihdr = be32(w) + be32(h) + Bytes{8, 0, 0, 0, 0};  // depth 8, grey, no interlace
  // zlib stream of nine zero bytes (filter type 0 and the first black pixels of row 0).
  const Bytes idat{'\x78', '\xda', '\x63', '\x60', '\x80', '\x02', '\x00', '\x00', '\x09', '\x00', '\x01'};
  return Bytes("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + chunk("IDAT", idat) + chunk("IEND", {});
}

/// `jpeg` with the frame size of its SOF0/SOF2 segment replaced by w x h.
Bytes patchJpegSize(Bytes jpeg, std::uint16_t w, std::uint16_t h) {
  for (std::size_t i = 2; i + 9 < jpeg.size();) {
    if (static_cast<unsigned char>(jpeg[i]) != 0xff) throw std::runtime_error("JPEG marker expected");
    const unsigned char marker = static_cast<unsigned char>(jpeg[i + 1]);
    const std::size_t len = (static_cast<unsigned char>(jpeg[i + 2]) << 8) | static_cast<unsigned char>(jpeg[i + 3]);
    if (marker == 0xc0 || marker == 0xc2) {
      jpeg[i + 5] = static_cast<char>(h >> 8);
      jpeg[i + 6] = static_cast<char>(h & 0xff);
      jpeg[i + 7] = static_cast<char>(w >> 8);
      jpeg[i + 8] = static_cast<char>(w & 0xff);
      return jpeg;
    }
    i += 2 + len;
  }
  throw std::runtime_error("no SOF segment");
}

}  // namespace

int main() {
  const cv::Mat photo = cv::imread("tests/data/equirect/indoor_1024x512.jpg", cv::IMREAD_GRAYSCALE);
  if (photo.empty()) throw std::runtime_error("run from the repository root");
  cv::Mat pano;
  cv::resize(photo, pano, {512, 256}, 0, 0, cv::INTER_AREA);
  const Bytes steep = readFile("tests/data/catadioptric/steep_mirror_800_ocamcalib.txt");
  const Bytes office = readFile("tests/data/catadioptric/mirror_office_ocamcalib.txt");

  // fuzz_calibration_yaml: the three lens models.
  const fs::path cy = kCorpus / "fuzz_calibration_yaml";
  writeFile(cy / "linear.yaml",
            "omni:\n  image_width: 720\n  image_height: 720\n  center: [359.5, 359.5]\n"
            "  radius_inner: 120\n  radius_outer: 300\n  azimuth_zero_deg: 0\n"
            "  azimuth_direction: cw\n  outer_edge: top\npanorama:\n  width: 1100\n  height: 110\n"
            "  horizon_row: 54.5\n  forward_column: 0\n");
  writeFile(cy / "mei_inline.yaml",
            "omni:\n  model: mei\n  image_width: 800\n  image_height: 800\n  xi: 0.92\n"
            "  K: [205.0, 0.3, 401.5, 0, 204.2, 398.0, 0, 0, 1]\n"
            "  D: [-0.04, 0.006, 0.0004, -0.0003]\n  radius_inner: 90\n  radius_outer: 330\n"
            "panorama: {width: 1100, height: 110}\n");
  writeFile(cy / "ocamcalib_missing_file.yaml",
            "omni:\n  model: ocamcalib\n  ocamcalib_file: calib_results.txt\n  mask: mask.png\n"
            "panorama: {width: 1100, height: 110, horizon_row: 54.5, forward_column: 0}\n");

  // fuzz_ocamcalib: the two OCamCalib files of tests/data.
  writeFile(kCorpus / "fuzz_ocamcalib" / "steep_mirror_800.txt", steep);
  writeFile(kCorpus / "fuzz_ocamcalib" / "mirror_office.txt", office);

  // fuzz_timestamps_tum: first half timestamps.txt, second half groundtruth.tum (read when
  // the first byte is odd; '#' is, '0' is not).
  const auto halves = [](Bytes a, Bytes b) {
    const std::size_t n = std::max(a.size(), b.size());
    a.resize(n, '\n');
    b.resize(n, '\n');
    return a + b;
  };
  const fs::path ct = kCorpus / "fuzz_timestamps_tum";
  writeFile(ct / "with_tum",
            halves("# file seconds\n000000.png 0.000\n000001.png 0.0333333\n000002.png 0.0666667\n",
                   "# timestamp tx ty tz qx qy qz qw\n0.000 0 0 0 0 0 0 1\n"
                   "0.0333333 0.01 0 0 0 0 0.00872654 0.999962\n"
                   "0.0666667 0.02 0.001 0 0 0 0.0174524 0.999848\n"));
  writeFile(ct / "timestamps_only",
            halves("000000.png 100.5\n000001.png 100.55\n000002.png 100.6\n", ""));

  // fuzz_frame_pipeline: mode byte (odd: image file, even: raw 128 x 128 grey pairs).
  const cv::Mat f0 = donut(pano, 128, 128, 0.0), f1 = donut(pano, 128, 128, 4.0);
  const fs::path cf = kCorpus / "fuzz_frame_pipeline";
  writeFile(cf / "png", "\x01" + encode(".png", f0));
  writeFile(cf / "jpeg", "\x01" + encode(".jpg", f0, {cv::IMWRITE_JPEG_QUALITY, 80}));
  writeFile(cf / "raw_pair", Bytes(1, '\0') + raw(f0) + raw(f1));
  // Regressions of the frame target: images whose header declares far more pixels than
  // OpenCV's decoder limit, and a JPEG cut short.
  const fs::path rf = kRegressions / "fuzz_frame_pipeline";
  writeFile(rf / "png_ihdr_60000x60000", "\x01" + craftedPng(60000, 60000));
  const Bytes jpeg = encode(".jpg", f0, {cv::IMWRITE_JPEG_QUALITY, 80});
  writeFile(rf / "jpeg_truncated", "\x01" + jpeg.substr(0, jpeg.size() / 2));
  writeFile(rf / "jpeg_sof_60000x60000", "\x01" + patchJpegSize(jpeg, 60000, 60000));

  // fuzz_lens_mask: [u16][calibration.yaml][u16][calib_results.txt][u16][omnidir.yml][mask].
  const auto lens = [](const Bytes& yaml, const Bytes& ocam, const Bytes& omnidir, const Bytes& mask) {
    return u16(yaml.size()) + yaml + u16(ocam.size()) + ocam + u16(omnidir.size()) + omnidir + mask;
  };
  const Bytes mask800 = encode(".png", discMask(800, 800));
  const fs::path cl = kCorpus / "fuzz_lens_mask";
  writeFile(cl / "ocamcalib_mask",
            lens("omni:\n  model: ocamcalib\n  ocamcalib_file: calib_results.txt\n  mask: mask.png\n"
                 "panorama: {width: 1100, height: 110}\n",
                 steep, "", mask800));
  writeFile(cl / "ocamcalib_office",
            lens("omni:\n  model: ocamcalib\n  ocamcalib_file: calib_results.txt\n"
                 "panorama: {width: 1100, height: 110}\n",
                 office, "", ""));
  {
    cv::FileStorage fsw(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fsw << "K" << (cv::Mat_<double>(3, 3) << 205.0, 0.3, 401.5, 0, 204.2, 398.0, 0, 0, 1);
    fsw << "D" << (cv::Mat_<double>(1, 4) << -0.04, 0.006, 0.0004, -0.0003);
    fsw << "xi" << (cv::Mat_<double>(1, 1) << 0.92);
    const Bytes omnidir = fsw.releaseAndGetString();
    writeFile(cl / "mei_omnidir_mask",
              lens("omni:\n  model: mei\n  omnidir_file: omnidir.yml\n  image_width: 800\n"
                   "  image_height: 800\n  radius_inner: 90\n  radius_outer: 330\n  mask: mask.png\n"
                   "panorama: {width: 1100, height: 110}\n",
                   "", omnidir, mask800));
  }
  writeFile(cl / "linear_mask",
            lens("omni:\n  image_width: 128\n  image_height: 128\n  center: [63.5, 63.5]\n"
                 "  radius_inner: 16\n  radius_outer: 60\n  mask: mask.png\n"
                 "panorama: {width: 200, height: 32}\n",
                 "", "", encode(".png", discMask(128, 128))));

  // fuzz_calibrate_frames: mode byte (bits 0-1 count - 1, bit 2 image files, bit 3 raw BGR,
  // bit 4 turn_left, bit 5 dark up cue, bit 6 propose a mask).
  const fs::path cc = kCorpus / "fuzz_calibrate_frames";
  writeFile(cc / "raw_grey_2", Bytes(1, '\x01') + raw(f0) + raw(f1));
  {
    Bytes files;
    for (int k = 0; k < 3; ++k) {
      const Bytes png = encode(".png", donut(pano, 160, 120, 6.0 * k, true));
      files += u32(png.size()) + png;
    }
    writeFile(cc / "png_3_mask", Bytes(1, static_cast<char>(0x40 | 0x04 | 2)) + files);
  }
  {
    Bytes files;
    for (int k = 0; k < 4; ++k) {
      const Bytes jpg = encode(".jpg", donut(pano, 128, 128, 5.0 * k), {cv::IMWRITE_JPEG_QUALITY, 70});
      files += u32(jpg.size()) + jpg;
    }
    writeFile(cc / "jpeg_4_turn_left", Bytes(1, static_cast<char>(0x10 | 0x04 | 3)) + files);
  }
  return 0;
}
