#pragma once
/// \file frame_selection.hpp
/// omnipose-calibrate works on a bounded number of frames, whatever it is given: at most N
/// of the M frames, spread evenly by their position in the given (sorted) list, so that a
/// long recording costs the time and memory of N frames and still covers the whole of it.

#include <cstddef>
#include <string>
#include <vector>

namespace omnipose::calibrate {

/// Default number of frames used (omnipose-calibrate --max-frames).
inline constexpr std::size_t kDefaultMaxFrames = 60;
/// Largest --max-frames accepted: the frames used are decoded and held together.
inline constexpr std::size_t kMaxFramesLimit = 500;

/// Positions (ascending, distinct) of at most `max_frames` of `count` frames, evenly spread:
/// index j is round(j (count - 1) / (n - 1)) for n = min(count, max_frames), so the first
/// and the last frame are always used; all of them when count <= max_frames. One frame
/// (max_frames == 1) is the first. Empty when count or max_frames is 0.
std::vector<std::size_t> selectEvenly(std::size_t count, std::size_t max_frames);

/// First position of the `max_frames` consecutive frames in the middle of `count` (0 when
/// count <= max_frames): a measurement that needs consecutive pairs (the rolling-shutter
/// readout, `--readout-from`) uses that run, `min(count, max_frames)` frames from there.
std::size_t centredRunStart(std::size_t count, std::size_t max_frames);

/// What the selection did, for stderr: "using 60 of 1000 frames, every 16.9th" or
/// "using all 10 frames".
std::string selectionMessage(std::size_t count, std::size_t selected);

}  // namespace omnipose::calibrate
