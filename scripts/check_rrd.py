#!/usr/bin/env python3
"""Check a Rerun .rrd recording with Rerun's own reader (rerun-sdk==0.36.3).

Usage:
  python scripts/check_rrd.py FILE --expect-entity /signals/force/f_e --samples N \
      [--expect-entity PATH ...] [--samples-for PATH=N ...] [--timeline sim_time] \
      [--expect-blueprint] [--expect-view TITLE ...] [--no-view TITLE ...] [--list] [--allow-no-footer]

--expect-entity PATH   PATH must exist in the recording (repeatable).
--samples N            every --expect-entity PATH has exactly N samples (rows) on the timeline.
--samples-for PATH=N   PATH has exactly N samples on the timeline (repeatable).
--timeline NAME        timeline to count on (default sim_time; wall_time for rig runs).
--expect-blueprint     the file carries a blueprint (the layout) and the command that makes it active
                       and the default (make_active and make_default), sent after the blueprint: a
                       viewer shows that layout, not one of its own.
--expect-view TITLE    the blueprint has a view named TITLE (repeatable), e.g. "force [N]".
--no-view TITLE        the blueprint has no view named TITLE (repeatable), e.g. "g [mm]" for an
                       impedance run.
--list                 print every entity with its sample count, then check.
--allow-no-footer      accept a file without the RRD footer (by default that means the writer
                       did not finish, and is a failure).

Exits 0 when every check holds, 1 with one line per failed check otherwise, 2 on usage or read
errors. Reads with `rerun.experimental.RrdReader` (chunk by chunk); a sample is a row of a
non-static chunk that has the timeline. The reader does not show blueprint activation commands:
those are read from the file's message frames (`activations`, below).
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


def read(file: Path, timeline: str, allow_no_footer: bool) -> tuple[set[str], Counter, list[str], set[str]]:
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
        blueprints = reader.blueprints()
        blueprint_ids = [bp.recording_id for bp in blueprints]
        views = view_names(reader, blueprints)
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
    return entities, samples, blueprint_ids, views


RRD_FOURCC = b"RRF2"
STREAM_HEADER_BYTES = 12  # FourCC, version, encoding options
MSG_END, MSG_SET_STORE_INFO, MSG_ARROW, MSG_BLUEPRINT_ACTIVATION = 0, 1, 2, 3


def _varint(buf: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if pos >= len(buf):
            raise ValueError("truncated varint")
        b = buf[pos]
        pos += 1
        value |= (b & 0x7F) << shift
        if not b & 0x80:
            return value, pos
        shift += 7


def _protobuf_fields(buf: bytes):
    """(field number, value) of a protobuf message: ints for varints, bytes for length-delimited."""
    pos = 0
    while pos < len(buf):
        key, pos = _varint(buf, pos)
        field, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = _varint(buf, pos)
        elif wire == 2:
            n, pos = _varint(buf, pos)
            value, pos = buf[pos : pos + n], pos + n
        elif wire == 1:
            value, pos = buf[pos : pos + 8], pos + 8
        elif wire == 5:
            value, pos = buf[pos : pos + 4], pos + 4
        else:
            raise ValueError(f"protobuf wire type {wire}")
        yield field, value


def activations(file: Path) -> list[dict]:
    """The blueprint activation commands of an .rrd, in file order, with the index of the message.

    The file is a stream header (FourCC `RRF2`, version, options: 12 bytes), then messages framed as
    kind (u64 LE) and length (u64 LE) before the payload; kind 3 is a BlueprintActivationCommand
    (protobuf: 1 blueprint_id {1 kind, 2 recording_id}, 2 make_active, 3 make_default); kind 0 ends the
    stream, which the footer follows (or, in concatenated files, another stream).
    """
    data = file.read_bytes()
    out = []
    pos, index = 0, 0
    while pos + STREAM_HEADER_BYTES <= len(data) and data[pos : pos + 4] == RRD_FOURCC:
        pos += STREAM_HEADER_BYTES
        while pos + 16 <= len(data):
            kind = int.from_bytes(data[pos : pos + 8], "little")
            length = int.from_bytes(data[pos + 8 : pos + 16], "little")
            payload = data[pos + 16 : pos + 16 + length]
            pos += 16 + length
            index += 1
            if kind == MSG_END:
                break
            if kind not in (MSG_SET_STORE_INFO, MSG_ARROW, MSG_BLUEPRINT_ACTIVATION):
                raise ValueError(f"unknown message kind {kind} at byte {pos - 16 - length}")
            if kind == MSG_BLUEPRINT_ACTIVATION:
                cmd = {"index": index, "recording_id": "", "make_active": False, "make_default": False}
                for field, value in _protobuf_fields(payload):
                    if field == 1:
                        for f, v in _protobuf_fields(value):
                            if f == 2:
                                cmd["recording_id"] = v.decode()
                    elif field == 2:
                        cmd["make_active"] = bool(value)
                    elif field == 3:
                        cmd["make_default"] = bool(value)
                out.append(cmd)
    return out


def blueprint_problems(file: Path, blueprint_ids: list[str]) -> list[str]:
    """Why the file's layout would not be what a viewer shows first (empty: it is)."""
    if not blueprint_ids:
        return ["no blueprint (layout) in the file"]
    try:
        cmds = activations(file)
    except ValueError as e:
        return [f"cannot read the message frames: {e}"]
    ours = [c for c in cmds if c["recording_id"] in blueprint_ids]
    if not ours:
        return [
            "the blueprint is never activated (no activation command for it): a viewer keeps its own "
            "layout"
        ]
    last = ours[-1]
    problems = []
    if not last["make_active"]:
        problems.append(
            "the blueprint is sent as a default only (make_active = false): a viewer that already has a "
            "layout keeps it"
        )
    if not last["make_default"]:
        problems.append("the blueprint is not made the default (make_default = false)")
    return problems


def view_names(reader, blueprints) -> set[str]:
    names: set[str] = set()
    for bp in blueprints:
        for chunk in reader.stream(store=bp):
            batch = chunk.to_record_batch()
            if "ViewBlueprint:display_name" in batch.schema.names:
                for cell in batch.column("ViewBlueprint:display_name").to_pylist():
                    names.update(cell or [])
    return names


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
    ap.add_argument("--expect-view", action="append", default=[], metavar="TITLE")
    ap.add_argument("--no-view", action="append", default=[], metavar="TITLE")
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

    entities, samples, blueprint_ids, views = read(args.file, args.timeline, args.allow_no_footer)
    if args.list:
        for e in sorted(entities):
            print(f"{e}\t{samples.get(e, 0)} samples on {args.timeline}")
        print("views: " + ", ".join(sorted(views)))

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
    if args.expect_blueprint:
        failures += blueprint_problems(args.file, blueprint_ids)
    for title in args.expect_view:
        if title not in views:
            failures.append(f"no view `{title}` in the layout (views: {', '.join(sorted(views))})")
    for title in args.no_view:
        if title in views:
            failures.append(f"the layout has a view `{title}` it must not have")

    for f in failures:
        print(f"check_rrd: {args.file}: {f}", file=sys.stderr)
    if failures:
        return 1
    checked = len(expected) + len(args.samples_for)
    active = ", active blueprint" if args.expect_blueprint else ""
    print(f"check_rrd: {args.file}: ok ({checked} entities checked on {args.timeline}{active})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
