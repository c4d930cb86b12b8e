"""optinav.io.read_euroc on the real EuRoC clip V1_01_micro."""

import numpy as np
import pytest

import optinav
from optinav.eval import ape
from optinav.io import read_euroc
from conftest import DATA

MICRO = DATA / "euroc" / "V1_01_micro"
MAV0 = MICRO / "mav0"


def csv_rows(path):
    return [line.split(",") for line in path.read_text().splitlines()
            if line.strip() and not line.startswith("#")]


def test_reads_cameras_imu_and_ground_truth():
    d = read_euroc(MICRO)
    assert d["mav0"] == str(MAV0)
    assert d["gnss"] is None and d["cam2"] is None and d["baro"] is None
    cam0 = d["cam0"]
    rows = csv_rows(MAV0 / "cam0" / "data.csv")
    assert cam0["t_ns"].dtype == np.int64
    assert cam0["t_ns"].tolist() == [int(r[0]) for r in rows]
    assert cam0["images"][0] == str(MAV0 / "cam0" / "data" / rows[0][1].strip())
    c = cam0["calibration"]
    assert c["resolution"] == (752, 480)
    assert c["distortion_model"] == "radial-tangential" and len(c["distortion"]) == 4
    assert c["body_from_cam"].shape == (4, 4)
    # cam1 lists frames the clip does not ship: skipped as `optinav vio` skips them.
    listed = len(csv_rows(MAV0 / "cam1" / "data.csv"))
    shipped = len(list((MAV0 / "cam1" / "data").iterdir()))
    assert listed > shipped == len(d["cam1"]["images"])

    imu = d["imu"]
    rows = csv_rows(MAV0 / "imu0" / "data.csv")
    assert imu["t_ns"].dtype == np.int64 and len(imu["t_ns"]) == len(rows)
    assert imu["t_ns"][0] == int(rows[0][0])
    assert imu["gyro_rad_s"].shape == imu["accel_m_s2"].shape == (len(rows), 3)
    assert imu["accel_m_s2"][0].tolist() == [float(v) for v in rows[0][4:7]]
    assert imu["calibration"]["rate_hz"] == 200

    gt = d["groundtruth"]
    rows = csv_rows(MAV0 / "state_groundtruth_estimate0" / "data.csv")
    assert gt["t_ns"].tolist() == [int(r[0]) for r in rows]
    assert gt["position"][0].tolist() == [float(v) for v in rows[0][1:4]]
    q = np.array([float(v) for v in rows[0][4:8]])
    assert np.allclose(gt["quaternion_wxyz"][0] * np.sign(gt["quaternion_wxyz"][0][0] * q[0]),
                       q / np.linalg.norm(q), atol=1e-12)
    # The ground truth dict is a trajectory for optinav.eval.
    self_ape = ape(gt, MAV0 / "state_groundtruth_estimate0" / "data.csv")
    assert self_ape["n"] == len(rows) and self_ape["max"] < 1e-12


def test_reads_the_nadir_camera_and_barometer_of_a_simulated_flight(tmp_path, optinav_bin):
    from conftest import run_cli
    seq = tmp_path / "seq"
    run_cli(optinav_bin, "sim", "--route", "drone", "--duration", "1", "--scale", "0.1",
            "--nadir-camera", "64x48", "--out", str(seq))
    d = read_euroc(seq)
    cam2 = d["cam2"]
    assert cam2["calibration"]["resolution"] == (64, 48)
    assert len(cam2["images"]) == 6  # 5 Hz over 1 s
    # Looking down the body's -z, image top towards the nose (docs/FORMATS.md).
    assert np.allclose(cam2["calibration"]["body_from_cam"][:3, :3],
                       [[0, -1, 0], [-1, 0, 0], [0, 0, -1]])
    baro = d["baro"]
    assert baro["t_ns"].dtype == np.int64 and baro["altitude_m"].shape == (21,)
    assert baro["calibration"]["rate_hz"] == 20
    gt = d["groundtruth"]
    # Every 10th ground-truth pose is a barometer epoch (20 Hz of 200 Hz); bias within 4 sigma.
    z = gt["position"][::10, 2][: len(baro["altitude_m"])]
    assert abs(np.mean(baro["altitude_m"] - z)) < 8.0


def test_errors_name_the_file_and_line(tmp_path):
    with pytest.raises(optinav.Error, match="image file not found") as info:
        read_euroc(MICRO, skip_missing_images=False)
    assert info.value.file == str(MAV0 / "cam1" / "data.csv") and info.value.line > 1
    with pytest.raises(optinav.Error, match="dataset folder not found"):
        read_euroc(tmp_path / "nothing")
    # A copy of the IMU with a malformed line 3.
    bad = tmp_path / "mav0" / "imu0"
    bad.mkdir(parents=True)
    (bad / "sensor.yaml").write_text((MAV0 / "imu0" / "sensor.yaml").read_text())
    lines = (MAV0 / "imu0" / "data.csv").read_text().splitlines()[:5]
    lines[2] = lines[2].replace(",", ",x", 1)
    (bad / "data.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(optinav.Error) as info:
        read_euroc(tmp_path)
    assert (info.value.file, info.value.line) == (str(bad / "data.csv"), 3)
