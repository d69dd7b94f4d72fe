"""The paper's adaptive impedance controller as a policy on pneuflex/ForceControl-v0: the baseline to beat.

    python crates/python/examples/adaptive_baseline.py [--episodes N]

`pneuflex.envs.adaptive_baseline(env)` wraps the scene's own adaptive controller (the one `pneuflex run`
simulates) as `policy(obs) -> action`, reading the plant's sensors through the environment. On the scene's own
values (the first line) the episode is pneuflex.run's adaptive run; then randomised environments.
"""

import argparse

import gymnasium

import pneuflex.envs as envs
from random_policy import describe


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=3)
    args = ap.parse_args(argv)
    env = gymnasium.make("pneuflex/ForceControl-v0").unwrapped
    policy = envs.adaptive_baseline(env)
    r = envs.rollout(env, policy, seed=0, options={"randomize": False})
    print(f"the scene's own values: return {r['return']:9.1f}, RMS force error {r['rms_force_error_n']:.3f} N")
    for seed in range(args.episodes):
        policy.reset()  # the adaptive law back to its initial g, p, d
        r = envs.rollout(env, policy, seed=seed)
        print(f"seed {seed}: {describe(r['draw'])}: return {r['return']:9.1f}, "
              f"RMS force error {r['rms_force_error_n']:6.3f} N")


if __name__ == "__main__":
    main()
