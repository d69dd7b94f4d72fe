"""A random policy on pneuflex/ForceControl-v0: the floor any learned policy must clear.

    python crates/python/examples/random_policy.py [--episodes N]

Each episode draws its environment (stiffness before and after the change, the change's time, mass and seal
friction); the policy draws valve commands uniformly in [-1, 1]. Prints each episode's draw, its return and the
RMS force error (the paper's metric over the whole episode).
"""

import argparse

import gymnasium
import numpy as np

import pneuflex.envs as envs


def describe(d):
    return (f"k {d['stiffness_n_per_m']:4.0f} -> {d['stiffness_after_n_per_m']:4.0f} N/m at {d['t_change_s']:.2f} s, "
            f"mass x{d['mass_scale']:.2f}, friction x{d['friction_scale']:.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=3)
    args = ap.parse_args(argv)
    env = gymnasium.make("pneuflex/ForceControl-v0")
    rng = np.random.default_rng(0)
    for seed in range(args.episodes):
        r = envs.rollout(env, lambda _obs: rng.uniform(-1, 1, 1).astype(np.float32), seed=seed)
        print(f"seed {seed}: {describe(r['draw'])}: return {r['return']:9.1f}, "
              f"RMS force error {r['rms_force_error_n']:6.2f} N over {r['steps']} steps")


if __name__ == "__main__":
    main()
