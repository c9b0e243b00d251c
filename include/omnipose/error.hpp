#pragma once
/// \file error.hpp
/// Errors as values for every expected failure (bad frame, device gone, timeout, fit did
/// not converge). The message lives in a fixed buffer, so creating, copying and returning
/// an Error never touches the heap: the per-frame path stays allocation-free even when a
/// frame is rejected.

#include <array>
#include <cstdarg>
#include <cstdio>
#include <expected>
#include <string_view>

namespace omnipose {

/// What went wrong, coarse enough for a caller to decide what to do next.
enum class ErrorCode {
  kInvalidArgument,    ///< a parameter or option is out of range
  kNotFound,           ///< file, directory or device does not exist
  kIoError,            ///< read/write/ioctl failed
  kBadFrame,           ///< frame unreadable, wrong size, or without content (all black)
  kTimeout,            ///< nothing arrived in time
  kNoDevice,           ///< no camera / device present
  kBusy,               ///< device in use by another process
  kUnsupportedFormat,  ///< the device or file offers no usable pixel format
  kDisconnected,       ///< the device went away while streaming
  kEndOfStream,        ///< a finite source has delivered its last frame
  kIllConditioned,     ///< too few or degenerate measurements for a unique solution
  kImplausible,        ///< a frame that decodes but whose motion cannot be believed (a
                       ///< glitching camera: torn, repeated, flipped or foreign frame)
};

/// Short lower-case name of a code ("bad_frame", "timeout", ...), for logs and status text.
constexpr std::string_view toString(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument: return "invalid_argument";
    case ErrorCode::kNotFound: return "not_found";
    case ErrorCode::kIoError: return "io_error";
    case ErrorCode::kBadFrame: return "bad_frame";
    case ErrorCode::kTimeout: return "timeout";
    case ErrorCode::kNoDevice: return "no_device";
    case ErrorCode::kBusy: return "busy";
    case ErrorCode::kUnsupportedFormat: return "unsupported_format";
    case ErrorCode::kDisconnected: return "disconnected";
    case ErrorCode::kEndOfStream: return "end_of_stream";
    case ErrorCode::kIllConditioned: return "ill_conditioned";
    case ErrorCode::kImplausible: return "implausible";
  }
  return "unknown";
}

/// An error code with a human-readable message (truncated to kCapacity - 1 characters).
class Error {
 public:
  static constexpr std::size_t kCapacity = 256;

  Error() = default;
  Error(ErrorCode code, std::string_view message) : code_(code) {
    const std::size_t n = message.size() < kCapacity - 1 ? message.size() : kCapacity - 1;
    for (std::size_t i = 0; i < n; ++i) text_[i] = message[i];
    text_[n] = '\0';
  }

  /// printf-style construction without allocation: Error::format(ErrorCode::kBadFrame,
  /// "%s: %dx%d, expected %dx%d", path, w, h, W, H).
  [[gnu::format(printf, 2, 3)]] static Error format(ErrorCode code, const char* fmt, ...) {
    Error e;
    e.code_ = code;
    va_list args;
    va_start(args, fmt);
    std::vsnprintf(e.text_.data(), kCapacity, fmt, args);
    va_end(args);
    return e;
  }

  ErrorCode code() const { return code_; }
  std::string_view message() const { return std::string_view(text_.data()); }
  const char* c_str() const { return text_.data(); }

 private:
  ErrorCode code_ = ErrorCode::kInvalidArgument;
  std::array<char, kCapacity> text_{};
};

/// Result of an operation that may fail in an expected way.
template <typename T>
using Expected = std::expected<T, Error>;

/// Shorthand for returning a failure: `return fail(ErrorCode::kTimeout, "no frame in %d ms", ms);`
template <typename... Args>
[[nodiscard]] std::unexpected<Error> fail(ErrorCode code, const char* fmt, Args... args) {
  if constexpr (sizeof...(Args) == 0) {
    return std::unexpected(Error(code, fmt));
  } else {
    return std::unexpected(Error::format(code, fmt, args...));
  }
}

}  // namespace omnipose
