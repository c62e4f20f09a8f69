"""Recorded tracks (``sgjax.humans.tracks``): the ETH/UCY ``frame id x y`` format read into
padded arrays on a regular time grid, every malformed file refused with its file and line, a
rollout written as a track file and read back, windows that ``vmap`` batches; and the eight
ETH/UCY recordings read as their README counts them."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shared_data import SHARED, require

from sgjax.humans.tracks import (
    TrackFileError,
    read_tracks,
    track_windows,
    write_rollout_tracks,
)

ETH_UCY = SHARED / "pedestrians" / "eth_ucy"
# file: (rows, annotated frames, pedestrians), from the folder's README
COUNTS = {"biwi_eth.txt": (5492, 876, 360), "biwi_hotel.txt": (6543, 1168, 389),
          "students001.txt": (21813, 444, 415), "students003.txt": (17953, 541, 434),
          "crowds_zara01.txt": (5153, 872, 148), "crowds_zara02.txt": (9722, 1052, 204),
          "crowds_zara03.txt": (5005, 754, 137), "uni_examples.txt": (2747, 734, 118)}


def write(tmp_path, text, name="scene.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_small_file_reads_onto_its_grid(tmp_path):
    # frames 0, 10, 20, then a gap to 50; pedestrian 7 in 0-20, pedestrian 3 in 10-50
    path = write(tmp_path, "0\t7\t1.0\t2.0\n10\t7\t1.5\t2.0\n10\t3\t5.0\t5.0\n"
                           "20\t3\t5.0\t4.5\n20\t7\t2.0\t2.0\n50 3 5.0 3.0\n")
    tracks = read_tracks(path)
    assert tracks.frame_step == 10 and tracks.dt == 0.4
    assert tracks.frames.tolist() == [0, 10, 20, 30, 40, 50]
    assert tracks.ids.tolist() == [7, 3]  # in order of first appearance
    assert tracks.valid.tolist() == [[True, False], [True, True], [True, True],
                                     [False, False], [False, False], [False, True]]
    assert tracks.x[2].tolist() == [2.0, 5.0] and tracks.y[5, 1] == 3.0
    assert np.isnan(tracks.x[3]).all()


@pytest.mark.parametrize("text, line, words", [
    ("0 1 1.0 2.0\n10 1 1.0\n", 2, "3 fields"),
    ("0 1 1.0 2.0\n10 1 1.0 abc\n", 2, "'abc' is not a number"),
    ("0 1 1.0 2.0\n10.5 1 1.0 2.0\n", 2, "frame 10.5 is not a whole number"),
    ("0 1 1.0 2.0\n10 1 1.0 2.0\n0 2 1.0 2.0\n", 3, "frame 0 after frame 10"),
    ("0 1 1.0 2.0\n0 1 1.5 2.0\n", 2, "pedestrian 1 at frame 0 again"),
    ("0 1 1.0 2.0\n10 2 1.0 2.0\n20 1 1.0 2.0\n", 3, "pedestrian 1 reappears"),
    ("0 1 1.0 2.0\n10 1 1.0 2.0\n20 1 1.0 2.0\n25 1 1.0 2.0\n", 4, "off the file's grid"),
    ("0 1 1.0 inf\n", 1, "not finite"),
])
def test_a_malformed_file_is_refused_naming_its_file_and_line(tmp_path, text, line, words):
    path = write(tmp_path, text)
    with pytest.raises(TrackFileError, match=f"{path.name}:{line}: .*{words}"):
        read_tracks(path)


def test_an_empty_or_missing_file_is_refused(tmp_path):
    with pytest.raises(TrackFileError, match="no observations"):
        read_tracks(write(tmp_path, "\n\n"))
    with pytest.raises(TrackFileError, match="no such track file"):
        read_tracks(tmp_path / "missing.txt")


def test_a_rollout_written_as_tracks_reads_back(tmp_path):
    """Pedestrians of a rollout (one enters late, one leaves early) round-trip through the
    format to 0.1 mm; a pedestrian that comes back is refused, naming it."""
    rng = np.random.default_rng(0)
    steps, humans = 30, 5
    x, y = (rng.uniform(-5, 5, (steps, humans)).astype(np.float32) for _ in range(2))
    active = np.ones((steps, humans), bool)
    active[:7, 2] = False  # enters at step 7
    active[20:, 4] = False  # leaves after step 19
    path = write_rollout_tracks(tmp_path / "rollout.txt", x, y, active)
    tracks = read_tracks(path)
    order = np.argsort(tracks.ids)
    assert tracks.ids[order].tolist() == list(range(humans))
    np.testing.assert_array_equal(tracks.valid[:, order], active)
    np.testing.assert_allclose(tracks.x[:, order][active], x[active], atol=1e-4)
    np.testing.assert_allclose(tracks.y[:, order][active], y[active], atol=1e-4)
    active[25, 1] = False  # pedestrian 1 leaves for a step and comes back
    with pytest.raises(ValueError, match="pedestrian 1 enters the rollout 2 times"):
        write_rollout_tracks(tmp_path / "bad.txt", x, y, active)


def test_windows_pad_to_the_widest_and_vmap_over_them(tmp_path):
    path = write(tmp_path, "0 1 0.0 0.0\n10 1 0.4 0.0\n10 2 9.0 9.0\n20 1 0.8 0.0\n"
                           "20 2 9.0 8.6\n30 2 9.0 8.2\n30 3 1.0 1.0\n")
    tracks = read_tracks(path)
    every = track_windows(tracks, 2)
    assert every.x.shape == (3, 2, 3)  # the third window holds pedestrians 1, 2 and 3
    assert every.ids.tolist() == [[1, 2, -1], [1, 2, -1], [1, 2, 3]]
    assert not bool(every.valid[0, :, 2].any())  # padding
    whole = track_windows(tracks, 3, whole=True)  # only pedestrian 2 spans rows 1-3
    assert whole.ids.tolist() == [[1], [2]] and whole.start.tolist() == [0, 1]
    # the mean speed of each window's pedestrians, batched over windows (m/s)
    speed = jax.vmap(lambda w: jnp.sum(jnp.where(w.valid[1:] & w.valid[:-1], jnp.hypot(
        jnp.diff(w.x, axis=0), jnp.diff(w.y, axis=0)), 0.0)) / tracks.dt)(whole)
    np.testing.assert_allclose(np.asarray(speed), [2.0, 2.0], atol=1e-5)
    with pytest.raises(ValueError, match="windows of 9 rows, the recording has 4"):
        track_windows(tracks, 9)


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_the_eth_ucy_recordings_read_as_their_readme_counts(name):
    """Every recording: its rows, annotated frames and pedestrians as the README lists them,
    every position finite, people walking at human speeds."""
    path = require(ETH_UCY / name, "the ETH/UCY recordings")
    tracks = read_tracks(path)
    rows, frames, people = COUNTS[name]
    assert int(tracks.valid.sum()) == rows
    assert int(tracks.valid.any(axis=1).sum()) == frames
    assert tracks.ids.shape[0] == people and tracks.frame_step == 10
    step = np.hypot(np.diff(tracks.x, axis=0), np.diff(tracks.y, axis=0)) / tracks.dt
    median = float(np.nanmedian(step))
    # 0.5-1.5 m/s in seven of them; ETH's 2.45 m/s at 0.4 s per annotated frame is the
    # widely noted quirk of this copy's ETH frame numbers
    assert 0.3 < median < 3.0  # m/s
