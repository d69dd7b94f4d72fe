"""Learns the impedance controller's gains with the cross-entropy method, and compares them with the shipped ones.

    python crates/python/examples/cem_impedance.py [--iterations N] [--population P] [--episodes E]

The policy is one constant action of pneuflex/ForceControlImpedance-v0: (a_m, a_b) in [-1, 1]^2 sets the target
inertia m_d = m_d0 4^a_m and damping b_d = b_d0 4^a_b of the scene's impedance controller (paper-fig3: m_d0 and
b_d0 of its `impedance` run), which runs every tick. Each iteration draws P candidates from a Gaussian, scores
each on the same E randomised environments (common seeds, so candidates are compared on equal terms), and refits
the Gaussian to the best quarter. All P x E episodes step together in the Rust batch (`gymnasium.make_vec`).
At the end the learned gains and the shipped ones (a = 0) are scored on E environments neither has seen.
"""

import argparse

import gymnasium
import numpy as np

import pneuflex.envs  # noqa: F401  (registers the environments)


def returns(vec, actions, seeds):
    """Mean return of each candidate (rows of `actions`) over the episodes of `seeds` (each candidate the same)."""
    p, e = len(actions), len(seeds)
    vec.reset(seed=[s for _ in range(p) for s in seeds])
    a = np.repeat(actions, e, axis=0).astype(np.float32)
    total = np.zeros(p * e)
    live = np.ones(p * e, bool)
    while live.any():
        _, reward, terminated, truncated, _ = vec.step(a)
        total += np.where(live, reward, 0.0)
        live &= ~(terminated | truncated)  # an ended episode's autoreset is not counted
    return total.reshape(p, e).mean(axis=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=6)
    ap.add_argument("--population", type=int, default=16)
    ap.add_argument("--episodes", type=int, default=4)
    args = ap.parse_args(argv)
    p, e = args.population, args.episodes
    vec = gymnasium.make_vec("pneuflex/ForceControlImpedance-v0", num_envs=p * e,
                             vectorization_mode="vector_entry_point")
    rng = np.random.default_rng(0)
    mean, std = np.zeros(2), np.full(2, 0.5)
    train = list(range(100, 100 + e))
    for it in range(args.iterations):
        cand = np.clip(rng.normal(mean, std, (p, 2)), -1, 1)
        score = returns(vec, cand, train)
        elite = cand[np.argsort(score)[-max(2, p // 4):]]
        mean, std = elite.mean(axis=0), elite.std(axis=0) + 0.02
        print(f"iteration {it}: best return {score.max():9.1f}, mean a = ({mean[0]:+.3f}, {mean[1]:+.3f})")
    held_out = list(range(1000, 1000 + e))
    both = np.array([np.zeros(2), mean])
    shipped, learned = (returns(gymnasium.make_vec("pneuflex/ForceControlImpedance-v0", num_envs=2 * e,
                                                   vectorization_mode="vector_entry_point"), both, held_out))
    print(f"learned: m_d x{4 ** mean[0]:.2f}, b_d x{4 ** mean[1]:.2f} of the shipped gains")
    print(f"held-out return over {e} environments: shipped {shipped:9.1f}, learned {learned:9.1f}")
    return shipped, learned


if __name__ == "__main__":
    main()
