"""``python -m train.export RUN --format onnx --out actor.onnx``: a trained actor as a file a
robot runs without JAX (``train.run.onnx_export``: the ONNX graph and its JSON sidecar of
observation layout, action meaning and provenance). ``--format acting --out x.msgpack``: the
acting part of a checkpoint (every seed's weights and observation statistics, its config and
meta; ``train.run.checkpoint.save_acting``), which evaluation, ``train.transfer`` and export
read as they read the full one, at a fraction of its size."""

from __future__ import annotations

import argparse

from train.run.checkpoint import save_acting
from train.run.onnx_export import export_onnx

FORMATS = ("onnx", "acting")


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m train.export", description=__doc__.split(
        "\n\n")[0])
    p.add_argument("run", help="a run folder (the weights its final evaluation judged: the "
                   "final ones unless its config says evaluation.checkpoint: best) or a .msgpack")
    p.add_argument("--format", default="onnx", choices=FORMATS)
    p.add_argument("--out", required=True, help="the file to write (its sidecar beside it, "
                   ".json)")
    p.add_argument("--seed-index", type=int, default=None,
                   help="which seed of a multi-seed run (default: the one the checkpoint "
                        "names as best, else 0)")
    return p


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    try:
        if args.format == "acting":
            print(f"wrote {save_acting(args.run, args.out)}")
            return
        model, side = export_onnx(args.run, args.out, args.seed_index)
    except ValueError as err:
        raise SystemExit(f"train.export: {err}") from err
    print(f"wrote {model} and {side}")


if __name__ == "__main__":
    main()
