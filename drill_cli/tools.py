"""``drill-env speed`` and ``drill-env replay``: the performance benchmark and the rerun
viewer."""

from __future__ import annotations

import argparse
import sys


def cmd_speed(args: argparse.Namespace) -> int:
    from drill_env.tools.speed import FULL, QUICK, SECTIONS, parse_sections, run_speed
    from training.speed import RUNNER

    runners = {"training": RUNNER}
    try:
        sections = (parse_sections(args.sections, extra=runners)
                    if args.sections is not None else (*SECTIONS, *runners))
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--{err}") from None
    run_speed(sections, QUICK if args.quick else FULL, args.out, runners=runners)
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from drill_env.recording import check_recording, replay

    for path in args.paths:  # what the viewer would show as an empty page, refused here
        if path.is_dir():
            inside = sorted(p.name for p in path.glob("*.rrd"))
            raise argparse.ArgumentTypeError(
                f"FILE: {path} is a folder; give its recordings" + (
                    f": {', '.join(inside[:3])}{' ...' if len(inside) > 3 else ''}"
                    if inside else " (it holds no .rrd file)"))
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"FILE: no recording at {path}")
        if path.suffix != ".rrd":
            raise argparse.ArgumentTypeError(f"FILE: {path} is not a rerun recording (.rrd)")
        with path.open("rb") as f:  # rerun's files start "RRF" and a format version
            if f.read(3) != b"RRF":
                raise argparse.ArgumentTypeError(f"FILE: {path} is not a rerun recording "
                                                 "(no RRF header)")
        try:
            warning = check_recording(path)
        except ValueError as err:  # the library names its argument; the usage says FILE
            text = str(err)
            raise argparse.ArgumentTypeError(
                "FILE: " + text.removeprefix("path: ") if text.startswith("path: ") else text
            ) from None
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
    if args.port is not None and not args.web:
        raise argparse.ArgumentTypeError("--port: the web viewer's port; add --web")
    from drill_env.recording.replay import no_display

    if not args.web and no_display():
        raise argparse.ArgumentTypeError("no display here (DISPLAY is not set) for "
                                         "the native viewer; add --web to serve the web "
                                         "viewer instead")
    if args.web:
        print("serving the web viewer: open the URL on rerun's line below (its server keeps "
              "one core busy while it runs: Ctrl-C when done)", file=sys.stderr)
    try:  # the port is checked there, once, just before the viewer takes it
        code = replay(args.paths, web=args.web, web_viewer_port=args.port,
                      **({"bind": args.bind} if args.bind is not None else {}))
    except ValueError as err:
        for name, flag in (("web_viewer_port", "--port"), ("bind", "--bind")):
            if str(err).startswith(name):
                raise argparse.ArgumentTypeError(
                    f"{flag}{str(err).removeprefix(name)}") from None
        raise
    code = int(code) if isinstance(code, int) else 0
    if code not in (0, 130, 143) and not args.web:  # (a stale DISPLAY, no X server: only
        # rerun's own winit error; a fuzzing walkthrough)
        print(f"drill-env replay: the native viewer ended with status {code}: where it "
              "cannot open a window (a DISPLAY no server answers, a remote shell), add "
              "--web to serve the web viewer instead", file=sys.stderr)
    return code
