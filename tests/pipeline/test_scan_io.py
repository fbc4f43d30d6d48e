"""Scan loading: PCD/PLY codecs, real-sensor depth encodings, RGB-D folders, real scans."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.scan_io import (
    downsample,
    load_cloud,
    load_scan,
    lzf_decompress,
    parse_up,
    read_depth,
    read_pcd,
    read_ply,
)


def lzf_literals(data: bytes) -> bytes:
    """A valid LZF stream made of literal runs only (ctrl = run length - 1 < 32)."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def write_pcd(path, fields: dict, mode: str, width: int | None = None, height: int = 1):
    names = list(fields)
    arrs = [np.asarray(fields[n]) for n in names]
    n = len(arrs[0])
    types = ["F" if a.dtype.kind == "f" else "U" for a in arrs]
    head = (f"VERSION 0.7\nFIELDS {' '.join(names)}\nSIZE {' '.join('4' for _ in names)}\n"
            f"TYPE {' '.join(types)}\nCOUNT {' '.join('1' for _ in names)}\n"
            f"WIDTH {width or n}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n"
            f"DATA {mode}\n").encode()
    if mode == "ascii":
        body = "\n".join(" ".join(repr(float(a[i])) if a.dtype.kind == "f" else str(int(a[i]))
                                  for a in arrs) for i in range(n)).encode() + b"\n"
    elif mode == "binary":
        rec = np.zeros(n, dtype=[(nm, "<f4" if t == "F" else "<u4") for nm, t in zip(names, types, strict=True)])
        for nm, a in zip(names, arrs, strict=True):
            rec[nm] = a
        body = rec.tobytes()
    else:
        raw = b"".join(a.astype("<f4" if t == "F" else "<u4").tobytes()
                       for a, t in zip(arrs, types, strict=True))
        comp = lzf_literals(raw)
        body = struct.pack("<II", len(comp), len(raw)) + comp
    path.write_bytes(head + body)


def test_lzf_back_reference_repeats_period():
    # literal "abc", then a back reference of length 6 at distance 3 -> "abcabcabc"
    # ctrl = (len - 2) << 5 | (off - 1) >> 8 ; next byte = (off - 1) & 255
    stream = bytes([2]) + b"abc" + bytes([(6 - 2) << 5 | 0, 2])
    assert lzf_decompress(stream, 9) == b"abcabcabc"
    with pytest.raises(ValueError):
        lzf_decompress(stream, 10)


@pytest.mark.parametrize("mode", ["ascii", "binary", "binary_compressed"])
def test_pcd_round_trip_with_labels(tmp_path, mode):
    rng = np.random.default_rng(0)
    xyz = rng.random((50, 3)).astype(np.float32)
    label = rng.integers(0, 60, 50).astype(np.uint32)
    rgb = rng.integers(0, 2**24, 50).astype(np.uint32)
    p = tmp_path / f"c_{mode}.pcd"
    write_pcd(p, {"label": label, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "rgba": rgb}, mode)
    f, w, h = read_pcd(p)
    assert (w, h) == (50, 1)
    assert np.allclose(np.stack([f["x"], f["y"], f["z"]], 1), xyz, atol=1e-6)
    assert np.array_equal(f["label"].astype(np.int64), label)
    scan = load_cloud(p, label_divisor=1)
    assert np.array_equal(scan.instance, label.astype(np.int64))
    want = np.stack([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255], 1) / 255.0
    assert np.allclose(scan.colors, want)


def test_ply_binary_and_ascii_with_instance(tmp_path):
    rng = np.random.default_rng(1)
    xyz = rng.random((20, 3)).astype(np.float32)
    inst = rng.integers(0, 5, 20).astype(np.uint16)
    head = ("ply\nformat {fmt} 1.0\nelement vertex 20\nproperty float x\nproperty float y\n"
            "property float z\nproperty ushort instance\nend_header\n")
    rec = np.zeros(20, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "<u2")])
    rec["x"], rec["y"], rec["z"], rec["i"] = xyz[:, 0], xyz[:, 1], xyz[:, 2], inst
    (tmp_path / "b.ply").write_bytes(head.format(fmt="binary_little_endian").encode() + rec.tobytes())
    rows = "\n".join(f"{a!r} {b!r} {c!r} {d}" for (a, b, c), d in zip(xyz.tolist(), inst.tolist(), strict=True))
    (tmp_path / "a.ply").write_text(head.format(fmt="ascii") + rows + "\n")
    for name in ("a.ply", "b.ply"):
        f = read_ply(tmp_path / name)
        assert np.allclose(np.stack([f["x"], f["y"], f["z"]], 1), xyz, atol=1e-6)
        assert np.array_equal(load_cloud(tmp_path / name).instance, inst.astype(np.int64))


def test_depth_encodings(tmp_path):
    import cv2

    mm = np.array([[0, 1000, 2500], [65535 >> 3, 1234, 7]], dtype=np.uint16)
    # SUN RGB-D: stored value is mm rotated left by 3 bits
    rot = ((mm << 3) | (mm >> 13)).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "sun.png"), rot)
    assert np.allclose(read_depth(tmp_path / "sun.png", "sun-bitrot"), mm / 1000.0)
    # TUM: value / 5000
    cv2.imwrite(str(tmp_path / "tum.png"), mm)
    assert np.allclose(read_depth(tmp_path / "tum.png", "png", 5000.0), mm / 5000.0)
    # NYU raw: little-endian 16-bit PGM of disparity, 2047 invalid
    disp = np.array([[2047, 800, 1000]], dtype="<u2")
    (tmp_path / "nyu.pgm").write_bytes(b"P5\n3 1\n65535\n" + disp.tobytes())
    d = read_depth(tmp_path / "nyu.pgm", "nyu-disparity")
    assert d[0, 0] == 0.0
    assert np.allclose(d[0, 1:], 351.3 / (1092.5 - np.array([800.0, 1000.0])))
    # RAPter float32 .dat: int32 rows, int32 cols, float32 metres
    z = np.array([[0.0, 1.5], [2.25, 0.7]], dtype="<f4")
    (tmp_path / "d.dat").write_bytes(struct.pack("<ii", 2, 2) + z.tobytes())
    assert np.allclose(read_depth(tmp_path / "d.dat"), z)
    (tmp_path / "bad.dat").write_bytes(struct.pack("<ii", 3, 3) + z.tobytes())
    with pytest.raises(InputError, match="header says 3x3"):
        read_depth(tmp_path / "bad.dat")


def test_parse_up():
    assert np.array_equal(parse_up("-y"), [0, -1, 0])
    assert np.allclose(parse_up("0,0,2"), [0, 0, 1])
    with pytest.raises(InputError, match="--up"):
        parse_up("sideways")


def test_downsample_keeps_one_point_per_voxel_and_is_deterministic():
    rng = np.random.default_rng(2)
    pts = rng.random((200_000, 3))
    a, _, _ = downsample(pts, None, None, 5000)
    b, _, _ = downsample(pts[::-1].copy(), None, None, 5000)
    assert 1000 < len(a) <= 5000
    assert len(a) == len(b)


def test_rgbd_folder_backprojects_with_its_intrinsics(tmp_path):
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from rgbd_fixtures import raycast, write_frame

    from pipeline.camera import transform
    from pipeline.model import rotation_about_z

    box = (np.array([0.0, 0.0, 0.2]), rotation_about_z(0.3), np.array([0.5, 0.3, 0.4]))
    fr = raycast([box], eye=(1.5, -1.5, 1.2), target=(0, 0, 0.2))
    write_frame(fr, tmp_path / "f", instance=True)
    scan = load_scan(tmp_path / "f")
    assert scan.T_world_cam is not None and scan.intrinsics == fr.intr
    w = transform(scan.T_world_cam, scan.points)
    on_box = scan.instance == 1
    # box points lie on the box surface (mm quantisation of depth)
    q = np.abs((w[on_box] - box[0]) @ box[1]) - box[2] / 2
    assert np.all(np.abs(q.max(1)) < 4e-3)
    # ground points at z = 0
    assert np.all(np.abs(w[scan.instance == 0][:, 2]) < 4e-3)


def test_real_osd_matches_open3d_xyz_and_has_labels(real_data):
    import open3d as o3d

    p = real_data / "osd_stacked_boxes" / "test16.pcd"
    f, w, h = read_pcd(p)
    assert (w, h) == (640, 480)
    ours = np.stack([f["x"], f["y"], f["z"]], 1)
    ours = ours[np.all(np.isfinite(ours), 1)]
    theirs = np.asarray(o3d.io.read_point_cloud(str(p), remove_nan_points=True).points)
    assert ours.shape == theirs.shape and np.allclose(ours, theirs, atol=1e-6)
    scan = load_cloud(p)
    assert sorted(np.unique(scan.instance).tolist()) == [0, 2, 3, 4]  # table + 3 objects
    # organised cloud -> exact RGB-D frame with the Kinect default intrinsics
    assert scan.intrinsics.fx == 525.0 and scan.depth.shape == (480, 640)


REAL_CASES = [
    ("open3d_testdata_rgbd", dict(color="NYU_color.ppm", depth="NYU_depth.pgm",
                                  depth_format="nyu-disparity", intrinsics="525,525,319.5,239.5"),
     1.39, 6.69),
    ("open3d_testdata_rgbd", dict(color="TUM_color.png", depth="TUM_depth.png", depth_scale=5000,
                                  intrinsics="525,525,319.5,239.5"), 1.46, 9.33),
    ("open3d_testdata_rgbd", dict(color="SUN_color.jpg", depth="SUN_depth.png",
                                  depth_format="sun-bitrot", intrinsics="525,525,319.5,239.5"),
     1.06, 9.87),
    ("shao_kinect_boxes", dict(color="derived/3boxes_rgb_640x480.png", depth="3boxes_depth16bits.dat",
                               intrinsics="519.3033,518.1640,328.5095,252.8256"), 0.705, 3.216),
    ("shao_kinect_boxes", dict(color="derived/5boxes_rgb_640x480.png", depth="5boxes_depth16bits.dat",
                               intrinsics="519.3033,518.1640,328.5095,252.8256"), 1.071, 2.649),
    ("metric3d_nyu", dict(color="rgb_00050.jpg", depth="sync_depth_00050.png",
                          intrinsics="518.8579,519.46961,325.58245,253.73617"), 0.89, 8.27),
] + [("sunrgbd_mmdet3d", dict(color=f"00000{i}_image.jpg", depth=f"derived/00000{i}_depth_mm.png",
                              intrinsics="529.5,529.5,365,265"), None, None) for i in (1, 2, 3, 4)]


@pytest.mark.parametrize(("folder", "kw", "lo", "hi"), REAL_CASES,
                         ids=[f"{c[0]}-{c[1]['depth']}" for c in REAL_CASES])
def test_real_frames_load_with_documented_ranges(real_data, folder, kw, lo, hi):
    """Depth ranges quoted in each SOURCE.md are reproduced (the encodings are right)."""
    scan = load_scan(real_data / folder, **kw, max_depth=1e9)  # no range cut here
    z = scan.points[:, 2]
    if lo is None:  # SUN RGB-D: the range is quoted over its four frames, 1.05-8.0 m
        assert 1.04 <= z.min() < 2.0 and 7.0 < z.max() <= 8.01
    else:
        assert z.min() == pytest.approx(lo, abs=0.02)
        assert z.max() == pytest.approx(hi, abs=0.02)
    assert scan.image.shape[:2] == scan.depth.shape


def test_real_sunrgbd_points_npz(real_data):
    scan = load_cloud(real_data / "sunrgbd_mmdet3d" / "000001_lidar.npz")
    assert scan.n == 50000 and np.array_equal(scan.up, [0, 0, 1])
    assert scan.colors.min() >= 0 and scan.colors.max() <= 1


@pytest.mark.parametrize(("folder", "kw", "lo", "hi"), REAL_CASES,
                         ids=[f"{c[0]}-{c[1]['depth']}" for c in REAL_CASES])
def test_real_depth_file_alone_loads_like_the_documented_flags(real_data, folder, kw, lo, hi):
    """``unseen run <depth file>`` needs no flag for the known data sets."""
    flagged = load_scan(real_data / folder, **{**kw, **({"max_depth": 7.0} if "SUN_" in kw["depth"] else {})})
    alone = load_scan(real_data / folder / kw["depth"])
    a, b = alone.intrinsics, flagged.intrinsics
    assert np.allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy], atol=1e-4)
    assert (a.width, a.height) == (b.width, b.height)
    assert np.array_equal(alone.image, flagged.image)
    assert alone.points.shape == flagged.points.shape
    assert np.allclose(alone.points, flagged.points, atol=1e-5)
    assert any(n.startswith("recognised") for n in alone.notes)


def test_sunrgbd_intrinsics_come_from_calib_column_major(real_data):
    scan = load_scan(real_data / "sunrgbd_mmdet3d" / "derived" / "000002_depth_mm.png")
    i = scan.intrinsics
    assert (i.fx, i.fy, i.cx, i.cy, i.width, i.height) == (529.5, 529.5, 365.0, 265.0, 730, 530)
