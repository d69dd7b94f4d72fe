#!/usr/bin/env python3
"""Check a Rerun .rrd recording with Rerun's own reader (rerun-sdk==0.36.3).

Usage:
  python scripts/check_rrd.py FILE --expect-entity /signals/force/f_e --samples N \
      [--expect-entity PATH ...] [--samples-for PATH=N ...] [--timeline sim_time] \
      [--expect-blueprint] [--list] [--allow-no-footer]

--expect-entity PATH   PATH must exist in the recording (repeatable).
--samples N            every --expect-entity PATH has exactly N samples (rows) on the timeline.
--samples-for PATH=N   PATH has exactly N samples on the timeline (repeatable).
--timeline NAME        timeline to count on (default sim_time; wall_time for rig runs).
--expect-blueprint     the file also carries a blueprint (the default layout).
--list                 print every entity with its sample count, then check.
--allow-no-footer      accept a file without the RRD footer (by default that means the writer
                       did not finish, and is a failure).

Exits 0 when every check holds, 1 with one line per failed check otherwise, 2 on usage or read
errors. Reads with `rerun.experimental.RrdReader` (chunk by chunk); a sample is a row of a
non-static chunk that has the timeline.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

EXPECTED_VERSION = "0.36.3"


def norm(path: str) -> str:
    """Rerun prints entity paths with a leading slash; accept them with or without."""
    return "/" + path.strip().strip("/")


def read(file: Path, timeline: str, allow_no_footer: bool) -> tuple[set[str], Counter, int]:
    try:
        import rerun as rr
    except ImportError:
        sys.exit(f"check_rrd: the rerun Python SDK is missing: pip install rerun-sdk=={EXPECTED_VERSION}")
    if not hasattr(rr, "experimental") or not hasattr(rr.experimental, "RrdReader"):
        sys.exit(
            f"check_rrd: rerun-sdk {getattr(rr, '__version__', '?')} has no experimental.RrdReader; "
            f"install rerun-sdk=={EXPECTED_VERSION}"
        )
    import warnings

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            reader = rr.experimental.RrdReader(str(file))
        footerless = [w for w in caught if "no footer" in str(w.message)]
        if footerless and not allow_no_footer:
            print(
                f"check_rrd: {file}: incomplete recording: no RRD footer "
                "(the writer did not finish; pass --allow-no-footer to read it anyway)",
                file=sys.stderr,
            )
            sys.exit(1)
        n_blueprints = len(reader.blueprints())
        if not reader.recordings():
            sys.exit(f"check_rrd: {file}: no recording store in the file")
        entities: set[str] = set()
        samples: Counter = Counter()
        for chunk in reader.stream():
            path = norm(chunk.entity_path)
            entities.add(path)
            if not chunk.is_static and timeline in chunk.timeline_names:
                samples[path] += chunk.num_rows
    except Exception as e:  # the reader raises plain exceptions for corrupt or truncated files
        print(f"check_rrd: cannot read {file}: {e}", file=sys.stderr)
        sys.exit(2)
    return entities, samples, n_blueprints


def parse_pair(text: str) -> tuple[str, int]:
    path, sep, n = text.rpartition("=")
    if not sep or not path:
        raise argparse.ArgumentTypeError(f"expected PATH=N, got `{text}`")
    try:
        value = int(n)
    except ValueError:
        raise argparse.ArgumentTypeError(f"`{n}` in `{text}` is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"sample count must be >= 0 in `{text}`")
    return norm(path), value


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file", type=Path)
    ap.add_argument("--expect-entity", action="append", default=[], metavar="PATH")
    ap.add_argument("--samples", type=int, metavar="N")
    ap.add_argument("--samples-for", action="append", default=[], type=parse_pair, metavar="PATH=N")
    ap.add_argument("--timeline", default="sim_time")
    ap.add_argument("--expect-blueprint", action="store_true")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--allow-no-footer", action="store_true")
    args = ap.parse_args(argv)

    if args.samples is not None and args.samples < 0:
        ap.error("--samples must be >= 0")
    if args.samples is not None and not args.expect_entity:
        ap.error("--samples needs at least one --expect-entity")
    if not args.file.is_file():
        print(f"check_rrd: {args.file}: no such file", file=sys.stderr)
        return 2

    entities, samples, n_blueprints = read(args.file, args.timeline, args.allow_no_footer)
    if args.list:
        for e in sorted(entities):
            print(f"{e}\t{samples.get(e, 0)} samples on {args.timeline}")

    failures = []
    expected = [norm(p) for p in args.expect_entity]
    for path in expected:
        if path not in entities:
            failures.append(f"entity {path} not found")
        elif args.samples is not None and samples[path] != args.samples:
            failures.append(
                f"entity {path}: {samples[path]} samples on {args.timeline}, expected {args.samples}"
            )
    for path, n in args.samples_for:
        if path not in entities:
            failures.append(f"entity {path} not found")
        elif samples[path] != n:
            failures.append(f"entity {path}: {samples[path]} samples on {args.timeline}, expected {n}")
    if args.expect_blueprint and n_blueprints == 0:
        failures.append("no blueprint (default layout) in the file")

    for f in failures:
        print(f"check_rrd: {args.file}: {f}", file=sys.stderr)
    if failures:
        return 1
    checked = len(expected) + len(args.samples_for)
    print(f"check_rrd: {args.file}: ok ({checked} entities checked on {args.timeline})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
