"""Linear model of scenes/gripper.toml's two modes about its 10 N hold (docs/multibody.md "Two force loops on one
object"): `.venv/bin/python scripts/gripper_modes.py [path/to/pneuflex]`.

The valve's flow gains come from `pneuflex tf pneumatics/gripper-finger.toml --json` (mid-stroke); the hold is
x = 35 mm (0.03 m + 10 N / 2 kN/m) with p_a = 491 kPa, p_b = 414 kPa (the shipped impedance run at 2.9 s). Per
finger: chamber pressures (flow and compression), the spool's 5 ms lag, the inner PI on x_r - x, the impedance
filter m_d x_f'' + b_d x_f' = f_ref - f_e. Two modes:
- common: each finger (0.1 kg, seals 5 N s/m) against its pad (k, c); the object stays;
- differential: both fingers and the object move together (0.25 kg driven by two cylinders, seals 2 x 5 N s/m and
  the object's slide, 2 N s/m bare); the pads do not deform, so neither force loop sees it and x_r is common.
Left out: the seals' Coulomb friction (0.3 N, smooth over 2 mm/s) and the 1 ms sampling; the simulation has both.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
binary = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "target" / "release" / "pneuflex")
tf = json.loads(subprocess.run([binary, "tf", str(ROOT / "pneumatics" / "gripper-finger.toml"), "--json"],
                               check=True, capture_output=True, text=True).stdout)
R, T, N = 287.05, 293.15, 1.4
AA = np.pi / 4 * 0.010**2
AB = AA - np.pi / 4 * 0.004**2
X0 = 0.035
VA, VB = 1.5e-6 + AA * X0, 1.5e-6 + AB * (0.05 - X0)
PA, PB = 491e3, 414e3
KPA, KPB, KCA, KCB = tf["k_pa"], -tf["k_pb"], tf["k_ca"], tf["k_cb"]
TAU = 0.005


def system(mode, kp=10.0, ki=20.0, c_obj=2.0, k_obj=0.0, k_pad=2000.0, c_pad=5.0, m_d=2.0, b_d=300.0):
    """States: x, v, dp_a, dp_b, spool, PI integral, x_f, x_f'."""
    if mode == "differential":  # per cylinder: half the mass, damping and spring of the moving assembly
        m, c, k = 0.25 / 2, (5 + 5 + c_obj) / 2, k_obj / 2
    else:
        m, c, k = 0.1, 5 + c_pad, k_pad
    a = np.zeros((8, 8))
    a[0, 1] = 1
    a[1, 0], a[1, 1], a[1, 2], a[1, 3] = -k / m, -c / m, AA / m, -AB / m
    a[2, 1], a[2, 2], a[2, 4] = -N * PA * AA / VA, -N * R * T / VA * KCA, N * R * T / VA * KPA
    a[3, 1], a[3, 3], a[3, 4] = N * PB * AB / VB, -N * R * T / VB * KCB, -N * R * T / VB * KPB
    a[4, 0], a[4, 4], a[4, 5], a[4, 6] = -kp / TAU, -1 / TAU, 1 / TAU, kp / TAU
    a[5, 0], a[5, 6] = -ki, ki
    a[6, 7], a[7, 7] = 1, -b_d / m_d
    if mode == "common":
        a[7, 0], a[7, 1] = -k_pad / m_d, -c_pad / m_d
    return a


def oscillatory_pole(*args, **kw):
    ev = np.linalg.eigvals(system(*args, **kw))
    ev = ev[np.abs(ev.imag) > 1.0]
    p = ev[np.argmax(ev.real)]
    return p.real, abs(p.imag) / (2 * np.pi), -p.real / abs(p)


def threshold(key, lo, hi, unstable_above, **kw):
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        unstable = oscillatory_pole("differential", **{key: mid}, **kw)[0] > 0
        if unstable == unstable_above:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


print(f"gas spring per cylinder at the hold: {N * (PA * AA**2 / VA + PB * AB**2 / VB):.0f} N/m")
rows = [
    ("common, foam pads (2 kN/m, 5 N s/m)", "common", {}),
    ("common, rubber pads (20 kN/m, 10 N s/m)", "common", {"k_pad": 20000.0, "c_pad": 10.0}),
    ("differential, bare slide (2 N s/m)", "differential", {}),
    ("differential, centring spring 1000 N/m", "differential", {"k_obj": 1000.0}),
    ("differential, kp 5 /m", "differential", {"kp": 5.0}),
    # A [[springs]] entry's damping replaces the URDF joint's (the spring is the joint's motor).
    ("differential, the scene's fixture (100 N/m, 50 N s/m)", "differential", {"k_obj": 100.0, "c_obj": 50.0}),
]
for label, mode, kw in rows:
    re, f, zeta = oscillatory_pole(mode, **kw)
    print(f"{label:56s} pole {re:+7.2f} 1/s at {f:5.1f} Hz, damping ratio {zeta:+.3f}")
print(f"differential mode stable for object damping above {threshold('c_obj', 2.0, 500.0, False):.1f} N s/m "
      f"(kp 10 /m), or kp below {threshold('kp', 0.5, 10.0, True):.2f} /m (bare slide)")
