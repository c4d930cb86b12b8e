"""optinav.eval: ape/rpe from files and arrays, equal to `optinav eval ... --json`."""

import json
import re

import numpy as np
import pytest

import optinav
from optinav.eval import ape, rpe
from conftest import DATA, run_cli

TRAJ = DATA / "trajectories"
KITTI_GT, KITTI_ORB = TRAJ / "KITTI_00_gt.txt", TRAJ / "KITTI_00_ORB.txt"
FR1_GT, FR1_EST = TRAJ / "freiburg1_xyz-groundtruth.txt", TRAJ / "freiburg1_xyz-rgbdslam.txt"
STATS = ["rmse", "mean", "median", "std", "min", "max", "sse"]


def test_kitti_ape_equals_the_cli_to_the_last_printed_digit(optinav_bin, tmp_path):
    # The agreement of issue 23: evo's KITTI 00 test data, SE(3) alignment.
    out = tmp_path / "ape.json"
    proc = run_cli(optinav_bin, "eval", "ape", KITTI_GT, KITTI_ORB, "--align", "se3",
                   "--json", out)
    cli = json.loads(out.read_text())
    py = ape(str(KITTI_GT), str(KITTI_ORB), align="se3")
    assert py == cli  # every key, every number exactly (json.loads parses the printed digits)
    # The numbers as printed: the JSON's text and the table's 6 decimals.
    assert json.dumps(py, sort_keys=True) == json.dumps(cli, sort_keys=True)
    for name in STATS:
        line = re.search(rf"^\s*{name}\s+(\S+)$", proc.stdout, re.M).group(1)
        assert f"{py[name]:.6f}" == line, name
    assert py["n"] == 4541
    assert py["rmse"] == pytest.approx(1.303450, abs=1e-6)  # evo's figure (eval/evo_reference)


def test_kitti_arrays_give_the_file_numbers():
    gt, est = np.loadtxt(KITTI_GT), np.loadtxt(KITTI_ORB)
    assert gt.shape == (4541, 12)
    from_arrays = ape(gt, est, align="se3")
    from_files = ape(KITTI_GT, KITTI_ORB, align="se3")  # pathlib.Path works as a path
    assert from_arrays["ref"] is None and from_arrays["est"] is None
    assert from_files["ref"] == str(KITTI_GT)
    for key in STATS + ["n", "alignment", "association"]:
        assert from_arrays[key] == from_files[key], key
    # A list of rows is an array too; a mix of file and array works.
    mixed = ape(KITTI_GT, est.tolist(), align="se3")
    assert mixed["rmse"] == from_files["rmse"]


def test_rpe_equals_the_cli(optinav_bin, tmp_path):
    args = ["--align", "se3", "--delta", "10", "--unit", "m"]
    run_cli(optinav_bin, "eval", "rpe", KITTI_GT, KITTI_ORB, *args, "--json", tmp_path / "r.json")
    cli = json.loads((tmp_path / "r.json").read_text())
    py = rpe(str(KITTI_GT), str(KITTI_ORB), align="se3", delta=10, unit="m")
    assert py == cli
    assert py["n"] == 353 and py["delta_unit"] == "m"
    assert py["rmse"] == pytest.approx(0.226261, abs=1e-6)


def test_tum_rows_are_associated_by_time_exactly_as_the_files():
    # 6-decimal TUM stamps: an array loaded from the file gives the file's stamps exactly.
    files = ape(FR1_GT, FR1_EST, align="se3", pose_relation="full")
    arrays = ape(np.loadtxt(FR1_GT), np.loadtxt(FR1_EST), align="se3", pose_relation="full")
    assert arrays["association"]["matched"] == 785
    for key in STATS + ["association", "alignment"]:
        assert arrays[key] == files[key], key
    shifted = ape(FR1_GT, FR1_EST, align="se3", t_offset=0.5, max_diff=0.02)
    assert shifted["association"]["t_offset_s"] == 0.5
    assert shifted["rmse"] != files["rmse"]


def test_euroc_dict_trajectory():
    # The ground truth as optinav.io.read_euroc gives it: t_ns, position, quaternion_wxyz.
    rows = [line.split(",") for line in (TRAJ / "V102_groundtruth.csv").read_text().splitlines()
            if line and not line.startswith("#")]
    gt = {"t_ns": np.array([int(r[0]) for r in rows], dtype=np.int64),
          "position": np.array([[float(v) for v in r[1:4]] for r in rows]),
          "quaternion_wxyz": np.array([[float(v) for v in r[4:8]] for r in rows])}
    from_dict = ape(gt, TRAJ / "V102.txt", align="se3")
    from_file = ape(TRAJ / "V102_groundtruth.csv", TRAJ / "V102.txt", align="se3")
    assert from_dict["n"] == from_file["n"]
    assert from_dict["rmse"] == pytest.approx(from_file["rmse"], rel=1e-12)


def test_outputs_are_written(tmp_path):
    stats = ape(FR1_GT, FR1_EST, align="sim3", json=tmp_path / "s.json", plot=tmp_path / "p.svg",
                save_aligned=tmp_path / "aligned.txt")
    assert json.loads((tmp_path / "s.json").read_text()) == stats
    assert "<svg" in (tmp_path / "p.svg").read_text()
    assert len(np.loadtxt(tmp_path / "aligned.txt")) == stats["association"]["matched"]
    assert stats["alignment"]["mode"] == "sim3" and stats["alignment"]["scale"] != 1.0


def test_malformed_file_raises_with_file_and_line(optinav_bin, tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n3.0 0 zero 0 0 0 0 1\n")
    with pytest.raises(optinav.Error) as info:
        ape(FR1_GT, bad)
    e = info.value
    assert isinstance(e, RuntimeError)
    assert (e.file, e.line, e.field) == (str(bad), 3, "y")
    assert str(e).startswith(f"{bad}:3: field 'y': ")
    # The CLI's message is the same text.
    proc = run_cli(optinav_bin, "eval", "ape", FR1_GT, bad, ok=False)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1] == f"optinav eval: error: {e}"
    with pytest.raises(optinav.Error, match="cannot open|not found|No such file") as info:
        ape(tmp_path / "missing.txt", FR1_EST)
    assert info.value.file == str(tmp_path / "missing.txt")


def test_bad_arrays_name_the_row():
    est = np.loadtxt(FR1_EST)[:5].copy()
    est[3, 2] = np.nan
    with pytest.raises(optinav.Error) as info:
        ape(FR1_GT, est)
    assert (info.value.file, info.value.line, info.value.field) == ("est array", 4, "y")
    est[3, 2] = 0
    est[2, 0] = est[1, 0] - 1
    with pytest.raises(optinav.Error, match="goes backwards") as info:
        ape(FR1_GT, est)
    assert info.value.line == 3
    with pytest.raises(ValueError, match=r"N x 8 TUM rows .* got shape \(5, 7\)"):
        ape(FR1_GT, est[:, :7])
    with pytest.raises(ValueError, match="shape"):
        ape(FR1_GT, est, est_format="kitti")
    with pytest.raises(optinav.Error, match="no poses"):
        ape(FR1_GT, np.zeros((0, 8)))
    with pytest.raises(TypeError):
        ape(FR1_GT, object())


def test_invalid_options_raise_value_error_with_the_cli_message():
    with pytest.raises(ValueError, match=r"align: unknown mode 'se4' \(none\|se3"):
        ape(FR1_GT, FR1_EST, align="se4")
    with pytest.raises(ValueError, match="--max-diff must be >= 0"):
        ape(FR1_GT, FR1_EST, max_diff=-1)
    with pytest.raises(ValueError, match="unit: unknown unit"):
        rpe(FR1_GT, FR1_EST, unit="km")
    with pytest.raises(ValueError, match="delta"):
        rpe(FR1_GT, FR1_EST, delta=0)
    with pytest.raises(ValueError, match="plot-plane"):
        ape(FR1_GT, FR1_EST, plot_plane="ab")
