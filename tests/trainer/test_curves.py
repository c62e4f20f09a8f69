"""``train.reports.curves``: learning curves drawn from ``progress.csv``, and its errors naming
the file and column."""

import csv
import math

import pytest
from PIL import Image

from train.cli import COLUMNS
from train.reports.curves import main, plot_learning_curves, read_progress


def _write_run(folder, rows):
    folder.mkdir(parents=True)
    with (folder / "progress.csv").open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: row.get(k, "") for k in COLUMNS})
    return folder


def _rows(n, evaluated_every=2):
    return [{"steps": 1000 * (i + 1), "team_success": i / n, "robot_success": (i + 1) / n,
             "mean_return": 10.0 * i, "entropy": 0.69 - 0.01 * i,
             **({"eval_team_success": 0.5} if i % evaluated_every == 1 else {})}
            for i in range(n)]


def test_progress_is_read_with_empty_evaluation_cells_as_nan(tmp_path):
    run = _write_run(tmp_path / "run", _rows(4))
    columns = read_progress(run / "progress.csv")
    assert columns["steps"] == [1000.0, 2000.0, 3000.0, 4000.0]
    assert math.isnan(columns["eval_team_success"][0]) and columns["eval_team_success"][1] == 0.5


def test_one_and_several_runs_are_drawn(tmp_path, capsys):
    first = _write_run(tmp_path / "seed0", _rows(5))
    second = _write_run(tmp_path / "seed1", _rows(3, evaluated_every=10))  # never evaluated
    main([str(first)])
    assert f"wrote {first / 'learning_curve.png'}" in capsys.readouterr().out
    path = plot_learning_curves([first, second / "progress.csv"], tmp_path / "both.png")
    with Image.open(path) as image, Image.open(first / "learning_curve.png") as single:
        assert image.format == "PNG" and image.size == single.size


@pytest.mark.parametrize("content, message", [
    (None, "no such run folder or progress.csv"),
    ("steps,team_success\n", "no rows yet"),
    ("steps,team_success\n1,0.5\n", "no column robot_success, mean_return, entropy"),
    (",".join(COLUMNS) + "\n" + ",".join(["1"] * (len(COLUMNS) - 1) + ["x"]) + "\n",
     "column eval_robot_success"),
])
def test_bad_progress_files_name_the_file_and_column(tmp_path, content, message):
    path = tmp_path / "progress.csv"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ValueError, match=message) as error:
        read_progress(path)
    assert str(path) in str(error.value)


def test_several_runs_need_an_output_path(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main([str(tmp_path / "a"), str(tmp_path / "b")])
    assert "--out: required" in capsys.readouterr().err
