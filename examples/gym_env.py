"""Drive the Gymnasium environment: the built-in closed loop (zero action) and a random policy.

    python examples/gym_env.py            # both policies, the whole task (~10 s CPU: `time python examples/gym_env.py`)
    python examples/gym_env.py --stages initial clamping   # a short check

A zero action leaves the built-in closed-loop controller in charge, so its cutting error
matches ``continuum-sim run``'s ``cutting_tip_error_mm.mean`` (to within 10 %: the env
samples the error every control tick, the run every record tick). The random policy adds
uniform bending-coordinate corrections up to ``max_correction_rad`` per section.
"""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import numpy as np

import continuum_sim.env  # noqa: F401 - registers continuum_sim/SampleRemoval-v0


def episode(env: gym.Env, policy: str, seed: int) -> dict:
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    total, steps = 0.0, 0
    while True:
        action = np.zeros(env.action_space.shape, np.float32) if policy == "closed-loop" else env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        steps += 1
        if terminated or truncated:
            break
    return {"policy": policy, "steps": steps, "return": round(total, 3), **info}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", nargs="*", help="limit the episode to these stages (default: the whole task)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    env = gym.make("continuum_sim/SampleRemoval-v0", stages=tuple(args.stages) if args.stages else None)
    for policy in ("closed-loop", "random"):
        print(json.dumps(episode(env, policy, args.seed)))
    env.close()


if __name__ == "__main__":
    main()
