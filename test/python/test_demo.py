"""`make demo`, the README's main job: the four runs on one seed's room and the table it prints."""
from dynaorb.cli.demo import demo_runs, format_demo


def test_demo_shows_the_front_end_keeping_movers_out(tmp_path):
    # 30 of the demo's 60 frames keep CI short. Measured (seed 0, synchronous):
    # static 0.0022 m, no filter 0.167 m, `full` 0.0025 m with 44 % of the
    # image marked moving, ground-truth masks 0.0025 m.
    runs = demo_runs(tmp_path, frames=30, seed=0)
    by_name = {r.name: r for r in runs}
    assert list(by_name) == ["static scene", "dynamic scene, no filter", "dynamic scene, `full` front end",
                             "dynamic scene, ground-truth masks"]
    for r in runs:
        assert r.tracked == r.frames == 30, r
        assert r.ate_m is not None, r
    static = by_name["static scene"].ate_m
    assert static <= 0.01
    assert by_name["dynamic scene, no filter"].ate_m >= 10 * static   # the movers pull the trajectory
    assert by_name["dynamic scene, `full` front end"].ate_m <= 1.5 * static
    assert by_name["dynamic scene, ground-truth masks"].ate_m <= 1.5 * static
    assert 0.2 <= by_name["dynamic scene, `full` front end"].marked_moving <= 0.6
    assert by_name["static scene"].marked_moving is None  # no front end: its column stays empty
    table = format_demo(runs, "header").splitlines()
    assert table[0] == "header" and len(table) == 3 + len(runs)
    full_line = next(line for line in table if line.startswith("dynamic scene, `full`"))
    assert "% of the image" in full_line and "n/a" not in "".join(table)
