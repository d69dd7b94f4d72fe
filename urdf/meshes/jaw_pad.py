"""Writes jaw_pad.obj: a gripper finger's jaw pad, a 30 x 30 mm block 5 mm deep whose front 5 mm are
chamfered at 45 degrees down to a 20 x 20 mm contact face (convex: the box and the frustum share their
30 x 30 mm section). Pad frame: y = the squeeze direction (the contact face at y = 10 mm faces +y, the back
at y = 0 sits on the finger), x and z across, centred. Metres; run `python3 urdf/meshes/jaw_pad.py` to
regenerate (the file is committed: the URDF reads it)."""

from pathlib import Path

BACK_HALF_M = 0.015  # half width of the back and of the shoulder, m
FACE_HALF_M = 0.010  # half width of the contact face, m
SHOULDER_M = 0.005  # depth of the straight part, m
DEPTH_M = 0.010  # back to contact face, m


def square(y: float, h: float) -> list[tuple[float, float, float]]:
    """The four corners of a square section at depth y, counter-clockwise seen from +y."""
    return [(-h, y, -h), (-h, y, h), (h, y, h), (h, y, -h)]


def jaw_pad() -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    rings = [square(0.0, BACK_HALF_M), square(SHOULDER_M, BACK_HALF_M), square(DEPTH_M, FACE_HALF_M)]
    vertices = [v for r in rings for v in r]
    tris = []
    # The back (seen from -y) and the contact face (seen from +y), each two triangles, outward.
    tris += [(0, 3, 2), (0, 2, 1)]
    tris += [(8, 9, 10), (8, 10, 11)]
    # The sides between consecutive rings: quads (a, b, b', a') split in two, outward.
    for r in range(2):
        for k in range(4):
            a, b = 4 * r + k, 4 * r + (k + 1) % 4
            a2, b2 = a + 4, b + 4
            tris += [(a, b, b2), (a, b2, a2)]
    return vertices, tris


def main() -> None:
    vertices, tris = jaw_pad()
    lines = ["# Gripper jaw pad (urdf/meshes/jaw_pad.py): 30 x 30 x 10 mm, 45-degree chamfer to a 20 x 20 mm face; m"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in tris]
    Path(__file__).with_name("jaw_pad.obj").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
