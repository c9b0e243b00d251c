#pragma once
/// \file instance_lock.hpp
/// What one omniposed must not share with another: its camera and the LCM log it writes. A
/// second daemon configured with the same camera or log is refused at start-up, naming the
/// holder's PID (FileLock, file_io.hpp: released on exit and by the kernel after a kill).
///
/// The log's lock is a file beside the log (`run.lcm.lock`, makeLcmSink()); a V4L2 camera's
/// is an flock on its device node itself (the path resolved, so /dev/v4l/by-id/... and
/// /dev/video0 are one camera; a camera unplugged and plugged again may come back as a new
/// node). A libcamera camera is exclusive by libcamera itself (a second acquire fails:
/// LibcameraSource names it); a file source takes nothing (many daemons may replay one
/// recording).

#include "daemon/config.hpp"
#include "omnipose/file_io.hpp"

namespace omnipose::daemon {

/// Takes the camera's lock. Throws std::runtime_error naming the device and the holder
/// ("source: v4l2 /dev/video0 is in use by another omniposed (/dev/video0: held by process
/// 1234)"). Nothing is taken for a device path that does not exist (opening the source
/// then fails naming it), a libcamera camera or a file source.
FileLock lockSource(const SourceConfig& source);

}  // namespace omnipose::daemon
