"""Write the README's pictures of every shipped scenario to ``docs/img/<name>.png``."""

from pathlib import Path

from PIL import Image

import sgjax
from sgjax.render import draw_scenario

OUT = Path(__file__).resolve().parent.parent / "docs" / "img"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name in sgjax.registered():
        path = OUT / f"{name}.png"
        Image.fromarray(draw_scenario(sgjax.maps.load(name), width_px=360)).save(path)
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
