"""Write docs/img/generated_worlds.png: six sampled worlds of each generated family (seed 0),
each drawn by ``sgjax.evaluation.render.draw_scenario`` from its exported map file (walls,
graph, conflict zone, starts and goals)."""

from pathlib import Path

import numpy as np

from sgjax.environment.worlds import sample_maps, source_for
from sgjax.evaluation.render import draw_scenario, save_png
from sgjax.maps.generated.families import FAMILIES
from sgjax.maps.schema import parse_map

OUT = Path(__file__).resolve().parent.parent / "docs" / "img" / "generated_worlds.png"
PER_FAMILY, WIDTH = 6, 300


def main() -> None:
    rows = []
    for name in FAMILIES:
        tiles = []
        for data, valid in sample_maps(source_for(name), PER_FAMILY, 0):
            assert valid, data["name"]
            tile = draw_scenario(parse_map(data, source=data["name"]), width_px=WIDTH)
            tiles.append(tile)
        height = max(t.shape[0] for t in tiles)
        tiles = [np.pad(t, ((0, height - t.shape[0]), (0, 0), (0, 0)), constant_values=255)
                 for t in tiles]
        rows.append(np.concatenate(tiles, axis=1))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255)
            for r in rows]
    print(f"wrote {save_png(np.concatenate(rows, axis=0), OUT)}")


if __name__ == "__main__":
    main()
