"""optinav.maploc: a frame rendered from the NAIP 2017 image, located on a map of the 2009 image
(as the CLI test does), equal to `optinav map locate --json`."""

import math

import numpy as np
import pytest

import optinav
from optinav import maploc
from conftest import DATA, cli_json, read_pgm

NAIP = DATA / "geo" / "naip"
TRUTH = (47.0186, -99.1526)  # the vehicle position of the rendered frame
PRIOR = dict(prior=(47.0195, -99.1510), radius_m=250, heading=30)  # ~150 m and 5 deg off
TIMES = {"time_ms", "times_ms"}  # measured, so they differ between runs


def distance_m(a, b):
    dlat = (a[0] - b[0]) * 111_200
    dlon = (a[1] - b[1]) * 111_200 * math.cos(math.radians(a[0]))
    return math.hypot(dlat, dlon)


def without_times(d):
    return {k: v for k, v in d.items() if k not in TIMES}


@pytest.fixture(scope="module")
def naip(tmp_path_factory):
    """The 2009 map (built for a 256 x 256 camera, 90 deg, 640 m) and a 2017 frame."""
    tmp = tmp_path_factory.mktemp("naip")
    db = maploc.build_map(NAIP / "naip_20090818.tif", tmp / "naip2009.db", altitude=640, hfov=90,
                          frame_size=(256, 256))
    rendered = maploc.render_frame(NAIP / "naip_20170827.tif", tmp / "f2017.pgm", at=TRUTH,
                                   heading=35, frame_size=(256, 256))
    return db, tmp, rendered


def test_frame_of_another_year_is_located_as_by_the_cli(naip, optinav_bin):
    db, tmp, rendered = naip
    assert rendered["gsd_m"] > 0
    frame = tmp / "f2017.pgm"
    py = db.locate(str(frame), **PRIOR)
    cli = cli_json(optinav_bin, "map", "locate", "--map", tmp / "naip2009.db", "--image", frame,
                   "--prior", "47.0195,-99.1510", "--radius", "250", "--heading", "30", "--json")
    assert set(py) == set(cli)
    assert without_times(py) == without_times(cli)
    assert py["localized"], py["reason"]
    assert distance_m((py["lat"], py["lon"]), TRUTH) < 25
    assert abs(py["heading_deg"] - 35) < 3


def test_frame_arrays_grey_and_rgb(naip):
    db, tmp, _ = naip
    grey = read_pgm(tmp / "f2017.pgm")
    assert grey.shape == (256, 256)
    from_path = db.locate(tmp / "f2017.pgm", **PRIOR)
    from_array = db.locate(grey, **PRIOR)
    assert "image" not in from_array and from_path["image"] == str(tmp / "f2017.pgm")
    assert without_times(from_array) == without_times({k: v for k, v in from_path.items()
                                                        if k != "image"})
    rgb = np.repeat(grey[:, :, None], 3, axis=2)  # equal channels: the same grey frame
    assert db.locate(rgb, **PRIOR)["lat"] == from_array["lat"]
    assert db.locate(rgb, bgr=True, **PRIOR)["lat"] == from_array["lat"]
    # A non-contiguous view is copied, not misread.
    assert db.locate(rgb[:, :, 0], **PRIOR)["lat"] == from_array["lat"]


def test_attitude_altitude_and_hfov_are_taken(naip):
    db, tmp, _ = naip
    r = db.locate(tmp / "f2017.pgm", altitude=640, attitude=(0.5, -0.5), hfov=90, **PRIOR)
    assert r["localized"], r["reason"]
    assert distance_m((r["lat"], r["lon"]), TRUTH) < 25
    assert r["altitude_m"] == pytest.approx(640, rel=0.1)


def test_info_equals_the_cli(naip, optinav_bin):
    db, tmp, _ = naip
    assert db.info() == cli_json(optinav_bin, "map", "info", tmp / "naip2009.db", "--json")
    assert db.path == str(tmp / "naip2009.db")


def test_errors(naip, tmp_path):
    db, tmp, _ = naip
    with pytest.raises(optinav.Error, match="map database not found") as info:
        maploc.MapDatabase(tmp_path / "missing.db")
    assert info.value.file == str(tmp_path / "missing.db")
    with pytest.raises(optinav.Error, match="lies outside the map extent") as info:
        db.locate(tmp / "f2017.pgm", prior=(10, 10))
    assert info.value.field == "--prior"
    with pytest.raises(optinav.Error, match="cannot read image") as info:
        db.locate(tmp_path / "none.png", prior=TRUTH)
    assert info.value.file == str(tmp_path / "none.png")
    with pytest.raises(ValueError, match="--altitude must be positive"):
        db.locate(tmp / "f2017.pgm", altitude=-5)
    with pytest.raises(ValueError, match="method: unknown method 'sift'"):
        maploc.MapDatabase(tmp / "naip2009.db", method="sift")
    with pytest.raises(TypeError, match="uint8"):
        db.locate(np.zeros((64, 64), dtype=np.float32))
    with pytest.raises(ValueError, match="H x W"):
        db.locate(np.zeros((64, 64, 4), dtype=np.uint8))
