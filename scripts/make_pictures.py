"""Write the README's pictures of every shipped scenario to ``docs/img/<name>.png``: the
trajectories of one episode of 4 robots under the ``only_local`` baseline (seed 0), drawn by
``sgjax.evaluation.render.plot_trajectories`` (the same picture ``sgjax render`` writes)."""

from pathlib import Path

import jax

import sgjax
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.render import plot_trajectories, save_png

OUT = Path(__file__).resolve().parent.parent / "docs" / "img"


def main() -> None:
    for name in sgjax.registered():
        env, params = sgjax.make(name, num_agents=4)
        batch = run_episodes(env, params, "only_local", jax.random.key(0), 1, record=True)
        states = jax.tree.map(lambda leaf: leaf[:, 0], batch.states)
        length = int(batch.values["episode_length"][0])
        image = plot_trajectories(sgjax.maps.load(name), states, params, length,
                                  title=f"{name} / only_local", width_px=360)
        print(f"wrote {save_png(image, OUT / f'{name}.png')}")


if __name__ == "__main__":
    main()
