"""train.reports.marl_eval: reproduce's results.json in marl-eval's raw-data layout (marl-eval
0.0.4's own DiagnoseData and data_process_pipeline accepted the export of
docs/results/results.json; the package pins pandas 1.4.4, which has no wheel for Python 3.11,
so it is not a test dependency)."""

import json
import math

from train.reports.marl_eval import main, to_marl_eval

DOCUMENT = {
    "profile": "sgjax", "seeds": 2, "episodes": 3, "total_steps": 1000,
    "results": {"doorway": {
        "cadrl": {"4": {"team_success": [0.5, 1.0], "collisions": [0.1, None],
                        "team_success_by_episode": [[1, 0, 1], [1, 1, 1]]}},
        "only_local": {"4": {"team_success": [0.4], "collisions": [0.3],
                             "team_success_by_episode": [[1, 0, 0, 1, 0]]}}}},
}


def test_every_algorithm_has_the_same_runs_steps_and_episodes(tmp_path):
    exported = to_marl_eval(DOCUMENT)
    task = exported["sgjax"]["doorway_4robots"]
    assert set(task) == {"cadrl", "only_local"}
    for runs in task.values():
        assert list(runs) == ["seed_0", "seed_1"]
        for run in runs.values():
            assert set(run) == {"step_1", "absolute_metrics"}
            assert len(run["step_1"]["team_success"]) == 3  # the shared episodes
            assert len(run["step_1"]["collisions"]) == 1  # a seed's mean
    cadrl, only_local = task["cadrl"], task["only_local"]
    step = cadrl["seed_1"]["step_1"]
    assert step["step_count"] == 1000 and step["team_success"] == [1.0, 1.0, 1.0]
    assert math.isnan(step["collisions"][0])  # undefined for that seed: NaN, not dropped
    assert cadrl["seed_0"]["absolute_metrics"]["collisions"] == [0.1]
    # the untrained baseline: its first 3 episodes (those the seeds played), in every run
    assert only_local["seed_0"]["step_1"]["team_success"] == [1.0, 0.0, 0.0]
    assert only_local["seed_0"] == only_local["seed_1"]
    assert only_local["seed_0"]["step_1"]["step_count"] == 0
    (tmp_path / "results.json").write_text(json.dumps(DOCUMENT))
    main([str(tmp_path / "results.json"), "--out", str(tmp_path / "marl.json")])
    assert "sgjax" in json.loads((tmp_path / "marl.json").read_text())
