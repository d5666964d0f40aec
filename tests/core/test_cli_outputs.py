"""Output paths at the command line: a path that cannot be written is one line naming
the flag and exit status 2, checked before the work starts; missing parent folders
are created, for every command and every output flag alike; nothing is ever written
half (staged beside the target, renamed into place at the end)."""
from __future__ import annotations

import os
import stat

import cv2
import numpy as np
import pytest

from backend.cli import main

from .cli_files import files  # noqa: F401  (the fixture)

BOARD = "chessboard:9x6:25mm"


def no_permission(tmp_path) -> str:
    """A folder this process may not create files in: as root every permission bit is
    granted, but /sys still refuses (EACCES); otherwise a folder without write bits."""
    if os.geteuid() == 0:
        return "/sys/freecal-test"
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    return str(locked)


CASES = {  # name: (argv with {obs}, {cal}, {dir}, {noperm}; the flag named; words in the message)
    "calibrate -o names a folder": (["calibrate", "{obs}", "--method", "zhang", "-q", "-o", "{dir}"], "-o",
                                    ["is a folder", "name a file"]),
    "calibrate -o under a file": (["calibrate", "{obs}", "--method", "zhang", "-q", "-o", "{obs}/cal.json"], "-o",
                                  ["is a file, not a folder"]),
    "calibrate -o in /proc": (["calibrate", "{obs}", "--method", "zhang", "-q", "-o", "/proc/x.json"], "-o",
                              ["cannot create files in /proc/"]),
    "calibrate -o without permission": (["calibrate", "{obs}", "--method", "zhang", "-q", "-o", "{noperm}/cal.json"],
                                        "-o", ["permission denied"]),
    "calibrate --report names a file": (["calibrate", "{obs}", "--method", "zhang", "-q", "--report", "{obs}"],
                                        "--report", ["is a file, not a folder"]),
    "detect -o in /proc": (["detect", "{dir}", "--board", BOARD, "-q", "-o", "/proc/x.json"], "-o",
                           ["cannot create files in /proc/"]),
    "detect -o names a folder": (["detect", "{dir}", "--board", BOARD, "-q", "-o", "{dir}"], "-o", ["is a folder"]),
    "export -o names a folder": (["export", "{cal}", "--to", "opencv", "-o", "{dir}"], "-o", ["is a folder"]),
    "export -o ends with a slash": (["export", "{cal}", "--to", "opencv", "-o", "{dir}/new/"], "-o", ["is a folder"]),
    "export -o without permission": (["export", "{cal}", "--to", "opencv", "-o", "{noperm}/a/cal.yaml"], "-o",
                                      ["permission denied"]),
    "export --error-map in /proc": (["export", "{cal}", "--to", "opencv", "-o", "{dir}/cal.yaml", "--error-map",
                                     "/proc/e.npz"], "--error-map", ["cannot create files in /proc/"]),
    "export --error-map names a folder": (["export", "{cal}", "--to", "opencv", "-o", "{dir}/cal.yaml",
                                           "--error-map", "{dir}"], "--error-map", ["is a folder"]),
    "undistort -o names a file": (["undistort", "{cal}", "-o", "{obs}"], "-o", ["is a file, not a folder"]),
    "undistort -o in /proc": (["undistort", "{cal}", "-o", "/proc/maps"], "-o", ["cannot create files in /proc/"]),
    "synth -o names a file": (["synth", "-o", "{obs}"], "-o", ["is a file, not a folder"]),
    "synth -o without permission": (["synth", "-o", "{noperm}/set"], "-o", ["permission denied"]),
    "report -o names a folder": (["report", "{cal}", "-o", "{dir}"], "-o", ["is a folder", "report.html"]),
    "report --figures names a file": (["report", "{cal}", "-o", "{dir}/r.html", "--figures", "{obs}"], "--figures",
                                      ["is a file, not a folder"]),
    "diff --map in /proc": (["diff", "{cal}", "{cal}", "--map", "/proc/d.png"], "--map", ["cannot create files in /proc/"]),
    "one file for two outputs": (["export", "{cal}", "--to", "opencv", "-o", "{dir}/x", "--error-map", "{dir}/x"],
                                 "--error-map", ["also given to -o"]),
    "-o - and --json": (["calibrate", "{obs}", "--method", "zhang", "-q", "-o", "-", "--json"], "-o -",
                        ["both write to standard output"]),
}


def _tree(root) -> dict[str, bytes]:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"/") for p in sorted(root.rglob("*"))}


@pytest.mark.parametrize("case", list(CASES))
def test_an_output_that_cannot_be_written_is_one_line_and_exit_2(tmp_path, files, capsys, case):  # noqa: F811
    argv, flag, words = CASES[case]
    argv = [a.format(**files, noperm=no_permission(tmp_path)) for a in argv]
    before = _tree(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"freecal {argv[0]}: error: {flag}"), err
    for w in words:
        assert w in err, err
    assert _tree(tmp_path) == before, "nothing written, not even a probe or a half file"


@pytest.mark.slow
def test_missing_parent_folders_are_created_for_every_command_and_flag(tmp_path, files, capsys):  # noqa: F811
    """The same rule everywhere: -o, --error-map, --report (as mkdir -p would)."""
    new = tmp_path / "new"
    runs = [
        ["calibrate", files["obs"], "--method", "zhang", "-q", "-o", f"{new}/a/cal.json", "--report", f"{new}/b/report"],
        ["export", files["cal"], "--to", "opencv", "-o", f"{new}/c/cal.yaml", "--error-map", f"{new}/d/error.npz"],
        ["undistort", files["cal"], "-o", f"{new}/e/maps", "--size", "256x320"],
        ["synth", "-o", f"{new}/f/set"],
        ["report", files["cal"], files["obs"], "-o", f"{new}/g/report.html", "--figures", f"{new}/h/figures"],
        ["diff", files["cal"], files["cal"], "--map", f"{new}/i/diff.png"],
    ]
    for argv in runs:
        assert main(argv) == 0, capsys.readouterr().err
    for path in ("a/cal.json", "b/report/calibration.json", "b/report/residual_vectors.png", "c/cal.yaml",
                 "d/error.npz", "e/maps/maps.npz", "e/maps/rectified_camera.json", "f/set/train.json",
                 "g/report.html", "h/figures/coverage.png", "i/diff.png", "b/report/report.html"):
        assert (new / path).is_file() and (new / path).stat().st_size > 0, path
    assert not [p for p in new.rglob(".*")], "no staging file or folder left behind"
    assert np.load(new / "d/error.npz")["error_px"].ndim == 2
    assert cv2.FileStorage(str(new / "c/cal.yaml"), cv2.FILE_STORAGE_READ).getNode("camera_matrix").mat().shape == (3, 3)


def test_a_command_that_fails_half_way_leaves_nothing(tmp_path, files, capsys):  # noqa: F811
    """undistort: the first photo is rectified, the second is not an image. The
    folder it would have written (and created) is not there afterwards."""
    good, bad = tmp_path / "good.png", tmp_path / "bad.png"
    cv2.imwrite(str(good), np.full((1280, 1024), 128, np.uint8))
    bad.write_text("not an image")
    out = tmp_path / "out" / "rectified"
    assert main(["undistort", files["cal"], str(good), str(bad), "--size", "256x320", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.png: not an image" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_an_existing_file_is_replaced_whole_and_keeps_its_mode(tmp_path, files, capsys):  # noqa: F811
    target = tmp_path / "cal.yaml"
    target.write_text("old")
    target.chmod(0o640)
    link = tmp_path / "link.yaml"
    link.symlink_to(target)
    assert main(["export", files["cal"], "--to", "opencv", "-o", str(link)]) == 0
    assert link.is_symlink(), "the link is kept; the file it points to is replaced"
    assert "camera_matrix" in target.read_text() and stat.S_IMODE(target.stat().st_mode) == 0o640
    fresh = tmp_path / "fresh.yaml"
    old = os.umask(0o022)
    try:
        assert main(["export", files["cal"], "--to", "opencv", "-o", str(fresh)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o644, "a new file is not private (mkstemp's 0600)"


def test_a_device_is_written_not_replaced(files, capsys):  # noqa: F811
    """-o /dev/null discards the output; renaming onto it would replace the device (as root)."""
    assert main(["export", files["cal"], "--to", "opencv", "-o", "/dev/null", "--error-map", "/dev/null"]) == 0
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
