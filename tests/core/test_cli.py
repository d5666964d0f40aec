"""The freecal command as a user runs it: synth → calibrate → evaluate."""
import itertools
import json
import re

import pytest

from backend.cli import main


def test_synth_calibrate_evaluate(tmp_path, capsys):
    out = tmp_path / "set"
    assert main(["synth", "--kind", "asymmetric", "--seed", "1", "-o", str(out)]) == 0
    for name in ("train.json", "holdout.json", "truth.json"):
        assert (out / name).is_file()
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(out / "train.json"), "-o", str(cal), "-q", "--method", "bspline", "--intervals", "8",
                 "--lambda-smooth", "100"]) == 0
    printed = capsys.readouterr().out
    assert "overall" in printed and "rmse [px]" in printed
    doc = json.loads(cal.read_text())
    assert doc["format"] == "freecal.calibration/1" and doc["settings"]["intervals"] == [8, 8]
    assert main(["evaluate", str(cal), str(out / "holdout.json"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["rmse"] < 0.2 and len(result["views"]) > 3


def test_the_paper_model_on_a_fisheye_says_its_base_and_marks_the_grid_that_scored_best(tmp_path, capsys):
    """The summary's grid table shows the score that chose the grid (the views
    left out of each grid's joint fit), so the row marked chosen is the lowest;
    the model's words name the base "auto" took for the 200° lens."""
    out = tmp_path / "set"
    assert main(["synth", "--kind", "fisheye200", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(out / "train.json"), "-o", str(tmp_path / "cal.json"), "--method", "bspline"]) == 0
    printed = capsys.readouterr().out
    assert "B-spline field over the equidistant projection" in printed
    assert "base projection: equidistant, chosen by the initial camera's radial profile" in printed
    lines = printed.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("knot grid, bandwidth and smoothing")) + 3
    rows = list(itertools.takewhile(lambda r: r and re.fullmatch(r"\d+x\d+", r[0]), map(str.split, lines[start:])))
    assert len(rows) >= 2
    scored = [r for r in rows if "skipped" not in r]
    chosen = [r for r in scored if r[-1] == "*"]
    assert len(chosen) == 1 and float(chosen[0][3]) == min(float(r[3]) for r in scored)


def test_user_errors_exit_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "freecal.observations/1", "image_size": [10, 10], "views": []}')
    assert main(["calibrate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "views" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert main(["calibrate", str(tmp_path / "missing.json")]) == 2
    assert "no such file" in capsys.readouterr().err


@pytest.mark.slow
def test_calibrate_summary_and_demo_say_which_model_was_chosen(tmp_path, capsys):
    """OpenCV's own lens: the summary names the model chosen in words and
    marks it in the score table; the demo names the choice per lens, the
    field on the asymmetric wave. B-spline flags without --method bspline
    are an error that says so."""
    out = tmp_path / "set"
    assert main(["synth", "--kind", "radial", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(out / "train.json"), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "model chosen: OpenCV 5-coefficient model" in printed and "one standard error" in printed
    chosen = [line for line in printed.splitlines() if line.rstrip().endswith("*")]
    assert len(chosen) == 1 and "OpenCV 5-coefficient model" in chosen[0]
    assert main(["calibrate", str(out / "train.json"), "-q", "--intervals", "8"]) == 2
    assert "add --method bspline" in capsys.readouterr().err
    assert main(["demo"]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()
            if line.split() and line.split()[0] in ("radial", "fisheye", "asymmetric")}
    assert "OpenCV 5-coefficient model" in rows["radial"] and "B-spline field" in rows["asymmetric"]


def test_the_summary_says_how_many_corners_were_set_aside_as_misplaced(tmp_path, capsys):
    from calib_core.observations import Observations

    out = tmp_path / "synth"
    assert main(["synth", "--kind", "radial", "-o", str(out)]) == 0
    obs = Observations.load(out / "train.json")
    points = obs.views[0].image_points
    points[[10, 30, 50]] = points[[30, 50, 10]]  # three corners given each other's ids
    obs.save(tmp_path / "mislabelled.json")
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "mislabelled.json"), "-o", str(tmp_path / "cal.json"),
                 "--method", "zhang"]) == 0
    assert "3 corners set aside before the fit as misplaced (beyond the image, or not where their board " \
           "neighbours put them: wrong ids?)" in capsys.readouterr().out
