"""omnipose-mcap SOURCE OUT.mcap: a run as an MCAP file for Foxglove, Lichtblick or any MCAP
reader (the topics of omnipose.foxglove_topics).

SOURCE is a dataset directory, replayed through the library as omnipose-replay replays it
(same options, same poses), or an LCM log the daemon wrote (lcm-logger, or the daemon's own
``lcm.url: file://...?mode=w``): its pose_t, fit_diagnostics_t, status_t and
panorama_image_t messages, found by their type whatever the channel. A dataset's panorama
pictures are rate limited (--panorama-hz); a log has those the daemon published
(lcm.panorama_channel).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any, Dict, List, Optional, Tuple

EXIT_OK, EXIT_USAGE, EXIT_FAILED = 0, 2, 1


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="omnipose-mcap",
        description="Writes an omnipose run (a dataset directory replayed, or the daemon's LCM "
                    "log) as an MCAP file with Foxglove's schemas.")
    p.add_argument("source", help="a dataset directory or an LCM log file")
    p.add_argument("out", help="the MCAP file to write")
    p.add_argument("--config", help="dataset: daemon.yaml options (pipeline, keyframes, "
                   "plausibility, input), as omnipose-replay --config")
    p.add_argument("--calibration", help="dataset: a calibration.yaml instead of the dataset's")
    p.add_argument("--panorama-hz", type=float, default=2.0,
                   help="dataset: panorama pictures per second of the run's time (0: none; "
                   "default 2)")
    p.add_argument("--panorama-width", type=int, default=640,
                   help="dataset: the pictures' width at most, pixels (default 640)")
    p.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    return p


def read_run(path: str) -> Dict[str, List[Tuple[int, str, Any]]]:
    """{topic: [(log_time_ns, schema name, message)]} of an MCAP file omnipose-mcap wrote,
    read with the mcap library: Foxglove's protobuf messages decoded with the schemas in the
    file, JSON ones as dicts. Needs mcap and mcap-protobuf-support."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    factory = DecoderFactory()
    decoders: Dict[int, Any] = {}
    topics: Dict[str, List[Tuple[int, str, Any]]] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding == "json":
                decoded = json.loads(message.data)
            else:
                if channel.id not in decoders:
                    decoders[channel.id] = factory.decoder_for(channel.message_encoding, schema)
                decoded = decoders[channel.id](message.data)
            topics.setdefault(channel.topic, []).append(
                (message.log_time, schema.name if schema else "", decoded))
    return topics


class _Limiter:
    """At most `hz` events per second of the run's clock (0: none)."""

    def __init__(self, hz: float) -> None:
        self.period_ns = int(1e9 / hz) if hz > 0 else None
        self.last: Optional[int] = None

    def due(self, t_ns: int) -> bool:
        if self.period_ns is None:
            return False
        if self.last is not None and 0 <= t_ns - self.last < self.period_ns:
            return False
        self.last = t_ns
        return True


def _export_dataset(args: argparse.Namespace, topics) -> str:
    import omnipose
    from . import foxglove_topics as ft

    dataset = omnipose.open_dataset(args.source, calibration=args.calibration)
    cal = dataset.calibration
    limiter = _Limiter(args.panorama_hz)
    panoramas: dict = {}
    counts = {"pictures": 0}

    def picture(path: str, t_ns: int, windows) -> None:
        frame = omnipose.read_frame(path)
        kind = "omni" if tuple(frame.shape[:2]) == tuple(cal.frame_shape) else "panorama"
        if kind not in panoramas:
            panoramas[kind] = omnipose.Panorama(cal, kind)
        image = ft.panorama_picture(panoramas[kind].unwrap(frame), windows,
                                    width=args.panorama_width)
        topics.panorama(t_ns, omnipose.encode_jpeg(image))
        counts["pictures"] += 1

    def on_frame(index: int, path: str, result) -> None:
        if not result.ok:
            return
        rec = ft.record_from_result(result, index)
        topics.frame(rec)
        windows = ft.windows_from_result(result, index)
        if windows is not None:
            topics.windows(windows)
        if limiter.due(rec.time_ns):
            picture(path, rec.time_ns, windows)

    if args.config:
        run = omnipose.replay_with_config(args.source, args.config, calibration=args.calibration,
                                          on_frame=on_frame)
    else:
        run = omnipose.replay(args.source, calibration=args.calibration, on_frame=on_frame)
    end_ns = int(round(float(dataset.timestamps[-1]) * 1e9)) if len(dataset.timestamps) else 0
    topics.status(end_ns, {
        "source": os.path.abspath(args.source), "final": True, "frames": run.frames,
        "pairs": run.pairs, "skipped": run.skipped, "implausible": run.implausible,
        "lost": run.lost, "bridged": run.bridged, "gyro_frames": run.gyro_frames,
        "median_ms_per_frame": run.median_seconds_per_frame * 1e3, "log": run.log})
    for line in run.log:
        print(f"omnipose-mcap: {line}", file=sys.stderr)
    return (f"{run.frames} frames ({run.pairs} pairs, {run.skipped} skipped, {run.lost} lost), "
            f"{counts['pictures']} panorama pictures")


def _export_lcm_log(args: argparse.Namespace, topics) -> str:
    try:
        import lcm
    except ImportError:
        raise SystemExit("omnipose-mcap: reading an LCM log needs the lcm package "
                         "(pip install 'omnipose[foxglove]')")
    from .foxglove_topics import LcmDispatcher

    dispatcher = LcmDispatcher(topics)
    try:
        log = lcm.EventLog(args.source, "r")
    except (IOError, OSError, ValueError) as e:
        raise SystemExit(f"omnipose-mcap: {args.source}: not an LCM log: {e}")
    for event in log:
        if dispatcher.handle(event.channel, event.data) == "bad":
            print(f"omnipose-mcap: {args.source}: event {event.eventnum}: "
                  f"{dispatcher.last_error}", file=sys.stderr)
    log.close()
    c = dispatcher.counts
    if c["pose"] == 0:
        print(f"omnipose-mcap: {args.source}: no pose_t message in the log", file=sys.stderr)
    return (f"{c['pose']} poses, {c['fit']} window sets, {c['status']} statuses, "
            f"{c['panorama']} panorama pictures ({c['other']} other messages, "
            f"{c['bad']} undecodable)")


def main(argv: Optional[List[str]] = None) -> int:
    args = _parser().parse_args(argv)
    if not os.path.exists(args.source):
        print(f"omnipose-mcap: {args.source}: no such file or directory", file=sys.stderr)
        return EXIT_USAGE
    if os.path.exists(args.out) and not args.overwrite:
        print(f"omnipose-mcap: {args.out} exists (--overwrite replaces it)", file=sys.stderr)
        return EXIT_USAGE
    try:
        import foxglove
    except ImportError:
        print("omnipose-mcap: needs the foxglove-sdk package (pip install 'omnipose[foxglove]')",
              file=sys.stderr)
        return EXIT_FAILED
    from .foxglove_topics import RunTopics

    started = time.monotonic()
    context = foxglove.Context()
    writer = foxglove.open_mcap(args.out, allow_overwrite=args.overwrite, context=context)
    try:
        topics = RunTopics(context)
        if os.path.isdir(args.source):
            summary = _export_dataset(args, topics)
        else:
            summary = _export_lcm_log(args, topics)
    except BaseException as e:
        writer.close()
        os.remove(args.out)  # no half-written file left behind
        if isinstance(e, (ValueError, RuntimeError, OSError)):  # ConfigError is a ValueError
            print(f"omnipose-mcap: {e}", file=sys.stderr)
            return EXIT_FAILED
        raise
    writer.close()
    print(f"omnipose-mcap: {args.out}: {summary} in {time.monotonic() - started:.1f} s")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
