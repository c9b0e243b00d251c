"""omnipose-view: the daemon's LCM messages, live, for Foxglove or Lichtblick.

Subscribes to every channel of an LCM URL (the daemon's lcm.url; "" = LCM's default, UDP
multicast), recognises the daemon's messages by their type (pose_t, fit_diagnostics_t,
status_t, panorama_image_t; whatever the channel names) and serves them over the Foxglove
WebSocket protocol (foxglove-sdk) as the topics of omnipose.foxglove_topics. In Foxglove:
Open connection -> Foxglove WebSocket -> ws://ROBOT:8765. The daemon is not slowed by it (it
publishes the same messages whether or not a viewer listens); set lcm.fit_channel for the
windows and lcm.panorama_channel for pictures.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any, List, Optional

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class LcmBridge:
    """Every message on `lc` (an lcm.LCM) that is one of the daemon's, written to `topics` (a
    RunTopics). Call lc.handle_timeout() to move messages; counts says what came."""

    def __init__(self, lc: Any, topics: Any, channels: str = ".*") -> None:
        from .foxglove_topics import LcmDispatcher

        self.dispatcher = LcmDispatcher(topics)
        self._subscription = lc.subscribe(channels, self._on_message)
        self._lc = lc

    @property
    def counts(self) -> dict:
        return self.dispatcher.counts

    def _on_message(self, channel: str, data: bytes) -> None:
        if self.dispatcher.handle(channel, data) == "bad":
            print(f"omnipose-view: {self.dispatcher.last_error}", file=sys.stderr)

    def close(self) -> None:
        self._lc.unsubscribe(self._subscription)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="omnipose-view",
        description="Serves the daemon's LCM messages over the Foxglove WebSocket protocol.")
    p.add_argument("--lcm-url", default="",
                   help="the daemon's lcm.url (default: LCM's default, UDP multicast); a "
                   "file://LOG?speed=1 URL plays a recorded log")
    p.add_argument("--channels", default=".*",
                   help="regular expression of the channels to listen to (default: all)")
    p.add_argument("--host", default="0.0.0.0",
                   help="address to serve on (default 0.0.0.0: every interface)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765; 0: any free one)")
    return p


def main(argv: Optional[List[str]] = None) -> int:
    args = _parser().parse_args(argv)
    if not 0 <= args.port <= 65535:
        print(f"omnipose-view: --port {args.port}: expected 0..65535", file=sys.stderr)
        return EXIT_USAGE
    try:
        import foxglove
        import lcm
    except ImportError as e:
        print(f"omnipose-view: needs {e.name} (pip install 'omnipose[foxglove]')", file=sys.stderr)
        return EXIT_FAILED
    from .foxglove_topics import RunTopics

    try:
        lc = lcm.LCM(args.lcm_url)
    except (RuntimeError, OSError, ValueError) as e:
        print(f"omnipose-view: LCM URL \"{args.lcm_url}\": {e}", file=sys.stderr)
        return EXIT_FAILED
    context = foxglove.Context()
    try:
        server = foxglove.start_server(name="omnipose", host=args.host, port=args.port,
                                       context=context)
    except (RuntimeError, OSError) as e:
        print(f"omnipose-view: cannot serve on {args.host}:{args.port}: {e}", file=sys.stderr)
        return EXIT_FAILED
    bridge = LcmBridge(lc, RunTopics(context), args.channels)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"omnipose-view: serving on ws://{args.host}:{server.port} (LCM "
          f"\"{args.lcm_url or 'default'}\", channels {args.channels})", flush=True)
    status = EXIT_OK
    try:
        while not stop.is_set():
            try:
                lc.handle_timeout(200)
            except OSError as e:
                if args.lcm_url.startswith("file://"):  # the end of a recorded log
                    print("omnipose-view: the log ended; serving until stopped", flush=True)
                    while not stop.wait(0.5):
                        pass
                else:
                    print(f"omnipose-view: LCM URL \"{args.lcm_url}\": {e}", file=sys.stderr)
                    status = EXIT_FAILED
                break
    finally:
        bridge.close()
        server.stop()
    c = bridge.counts
    print(f"omnipose-view: {c['pose']} poses, {c['fit']} window sets, {c['status']} statuses, "
          f"{c['panorama']} pictures served ({c['other']} other messages, {c['bad']} "
          f"undecodable)")
    return status


if __name__ == "__main__":
    sys.exit(main())
