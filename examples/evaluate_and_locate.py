#!/usr/bin/env python3
"""optinav from Python, notebook style: each `# %%` cell runs on its own in Jupyter or VS Code.

Run it with Debian's interpreter and the module built by CMake:
    PYTHONPATH=build/python /usr/bin/python3 examples/evaluate_and_locate.py
It reads the project's test data (../shared/data, or $OPTINAV_SHARED_DATA) and writes into a
temporary folder, removed by the last cell unless $OPTINAV_KEEP_TEST_DIRS is set. ctest runs it
as python/example.
"""

# %% Setup
import os
import pathlib
import shutil
import tempfile

import numpy as np

import optinav
from optinav import eval as ev, io, maploc

ROOT = pathlib.Path(__file__).resolve().parent.parent
DATA = pathlib.Path(os.environ.get("OPTINAV_SHARED_DATA")
                    or os.environ.get("OPTINAV_SHARED_DATA_DEFAULT")
                    or ROOT.parent / "shared" / "data")
WORK = pathlib.Path(tempfile.mkdtemp(prefix="optinav_example_"))
optinav.set_log_level("warn")
print("optinav", optinav.__version__)

# %% Absolute pose error of ORB-SLAM2 on KITTI 00 (evo's test data), from files
gt_path = DATA / "trajectories" / "KITTI_00_gt.txt"
orb_path = DATA / "trajectories" / "KITTI_00_ORB.txt"
stats = ev.ape(gt_path, orb_path, align="se3")
print(f"APE  rmse {stats['rmse']:.6f} m, max {stats['max']:.6f} m over {stats['n']} poses")

# %% The same from numpy arrays (N x 12 KITTI rows): your own estimate needs no file
gt, orb = np.loadtxt(gt_path), np.loadtxt(orb_path)
assert ev.ape(gt, orb, align="se3")["rmse"] == stats["rmse"]

# %% Relative pose error per 100 m, rotation in degrees
rpe = ev.rpe(gt, orb, align="se3", delta=100, unit="m", pose_relation="angle_deg")
print(f"RPE  rmse {rpe['rmse']:.4f} deg per 100 m ({rpe['n']} pairs)")

# %% A EuRoC dataset: ground truth, IMU and image lists as arrays (int64 nanosecond stamps)
euroc = io.read_euroc(DATA / "euroc" / "V1_01_micro")
imu, truth = euroc["imu"], euroc["groundtruth"]
duration_s = (imu["t_ns"][-1] - imu["t_ns"][0]) * 1e-9
path_m = np.linalg.norm(np.diff(truth["position"], axis=0), axis=1).sum()
print(f"EuRoC {len(euroc['cam0']['images'])} frames, {len(imu['t_ns'])} IMU samples over "
      f"{duration_s:.1f} s, ground-truth path {path_m:.2f} m")

# %% A map of a 2009 orthophoto, and a frame of the 2017 one located on it
naip = DATA / "geo" / "naip"
db = maploc.build_map(naip / "naip_20090818.tif", WORK / "naip2009.db", altitude=640, hfov=90,
                      frame_size=(256, 256))
truth_latlon = (47.0186, -99.1526)
maploc.render_frame(naip / "naip_20170827.tif", WORK / "frame.png", at=truth_latlon, heading=35,
                    frame_size=(256, 256))
fix = db.locate(WORK / "frame.png", prior=(47.0195, -99.1510), radius_m=250, heading=30)
print(f"fix  localized={fix['localized']} by {fix['method']}: {fix['lat']:.6f}, {fix['lon']:.6f} "
      f"(+-{fix['position_sigma_m']:.1f} m), heading {fix['heading_deg']:.1f} deg, "
      f"{fix['inliers']} inliers")

# %% How far from the truth (a local flat-earth distance is enough at this scale)
north_m = (fix["lat"] - truth_latlon[0]) * 111_200
east_m = (fix["lon"] - truth_latlon[1]) * 111_200 * np.cos(np.radians(truth_latlon[0]))
error_m = float(np.hypot(north_m, east_m))
print(f"fix error {error_m:.1f} m")
assert fix["localized"] and error_m < 25, fix

# %% Clean up the temporary folder (kept with OPTINAV_KEEP_TEST_DIRS=1, to look at the map and frame)
if os.environ.get("OPTINAV_KEEP_TEST_DIRS"):
    print(f"kept {WORK}")
else:
    shutil.rmtree(WORK)
