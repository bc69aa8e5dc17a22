"""Point-cloud file reading: every format round-trips, bad files raise clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from graspsim.errors import GraspsimError, PointCloudError
from graspsim.perception.cloud_input import check_cloud, lzf_decompress, read_point_cloud

PTS = np.random.default_rng(7).uniform(-0.1, 0.1, size=(50, 3)).astype(np.float32)


def _pcd_header(n, data, fields="x y z rgb", size="4 4 4 4", typ="F F F U", count="1 1 1 1"):
    return (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\n"
            f"SIZE {size}\nTYPE {typ}\nCOUNT {count}\nWIDTH {n}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n").encode()


def _records(pts):
    rec = np.zeros(len(pts), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4")])
    rec["x"], rec["y"], rec["z"], rec["rgb"] = pts[:, 0], pts[:, 1], pts[:, 2], 0xFF00FF
    return rec


def _lzf_literals(data: bytes) -> bytes:
    """Valid LZF stream made of literal runs only (no compression)."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i : i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def test_pcd_ascii_binary_and_compressed_round_trip(tmp_path):
    ascii_rows = "\n".join(f"{x:.6f} {y:.6f} {z:.6f} 4294967295" for x, y, z in PTS)
    (tmp_path / "a.pcd").write_bytes(_pcd_header(len(PTS), "ascii") + ascii_rows.encode() + b"\n")
    (tmp_path / "b.pcd").write_bytes(_pcd_header(len(PTS), "binary") + _records(PTS).tobytes())
    rec = _records(PTS)
    soa = b"".join(rec[name].tobytes() for name in ("x", "y", "z", "rgb"))
    comp = _lzf_literals(soa)
    body = np.array([len(comp), len(soa)], "<u4").tobytes() + comp
    (tmp_path / "c.pcd").write_bytes(_pcd_header(len(PTS), "binary_compressed") + body)
    for name, fmt in [("a.pcd", "pcd/ascii"), ("b.pcd", "pcd/binary"), ("c.pcd", "pcd/binary_compressed")]:
        cloud = read_point_cloud(tmp_path / name)
        assert cloud.fmt == fmt and cloud.n_dropped == 0 and cloud.points.shape == PTS.shape
        np.testing.assert_allclose(cloud.points, PTS, atol=1e-6)


def test_lzf_back_references_decode():
    # literal "abc", long back-reference (9 bytes, offset 3), short one (4 bytes, offset 6)
    stream = bytes([0x02]) + b"abc" + bytes([0xE0, 0x00, 0x02]) + bytes([0x40, 0x05])
    assert lzf_decompress(stream, 16) == b"abcabcabcabc" + b"abca"
    with pytest.raises(PointCloudError, match="header says 20"):
        lzf_decompress(stream, 20)
    with pytest.raises(PointCloudError, match="before the start"):
        lzf_decompress(bytes([0x40, 0x05]), 4)


def test_organised_pcd_nan_points_are_dropped_and_counted(tmp_path):
    pts = PTS.copy()
    pts[::5] = np.nan
    (tmp_path / "o.pcd").write_bytes(_pcd_header(len(pts), "binary") + _records(pts).tobytes())
    cloud = read_point_cloud(tmp_path / "o.pcd")
    assert cloud.n_dropped == 10 and cloud.n_read == 50 and len(cloud.points) == 40
    assert np.all(np.isfinite(cloud.points))


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_round_trip(tmp_path, fmt):
    head = (f"ply\nformat {fmt} 1.0\ncomment test\nelement vertex {len(PTS)}\n"
            "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "element face 0\nproperty list uchar int vertex_indices\nend_header\n").encode()
    if fmt == "ascii":
        body = "\n".join(f"{x:.7f} {y:.7f} {z:.7f} 255" for x, y, z in PTS).encode() + b"\n"
    else:
        o = "<" if fmt.endswith("little_endian") else ">"
        rec = np.zeros(len(PTS), [("x", o + "f4"), ("y", o + "f4"), ("z", o + "f4"), ("r", "u1")])
        rec["x"], rec["y"], rec["z"] = PTS.T
        body = rec.tobytes()
    (tmp_path / "p.ply").write_bytes(head + body)
    np.testing.assert_allclose(read_point_cloud(tmp_path / "p.ply").points, PTS, atol=1e-6)


def test_npy_and_text_formats(tmp_path):
    np.save(tmp_path / "p.npy", PTS.astype(float))
    np.savetxt(tmp_path / "p.xyz", PTS, header="x y z")
    np.savetxt(tmp_path / "p.csv", np.column_stack([PTS, np.ones(len(PTS))]), delimiter=",")
    for name in ("p.npy", "p.xyz", "p.csv"):
        np.testing.assert_allclose(read_point_cloud(tmp_path / name).points, PTS, atol=1e-6)


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("trunc.pcd", _pcd_header(50, "binary") + _records(PTS).tobytes()[:300], "truncated binary PCD"),
        ("rows.pcd", _pcd_header(2, "ascii") + b"0 0 0 1\n0 0\n", "row 2 has 2 values, expected 4"),
        ("noxyz.pcd", _pcd_header(1, "ascii", fields="x y w rgb") + b"0 0 0 1\n", "lack \\['z'\\]"),
        ("count.pcd", _pcd_header(1, "ascii", size="4 4 4") + b"0 0 0 1\n", "4 FIELDS but 3 SIZE"),
        ("nodata.pcd", b"VERSION 0.7\nFIELDS x y z\n", "no DATA line"),
        ("lzf.pcd", _pcd_header(50, "binary_compressed") + b"\x10\x00\x00\x00", "truncated"),
        ("mode.pcd", _pcd_header(1, "packed") + b"\x00", "unsupported PCD DATA 'packed'"),
        ("nan.xyz", b"nan nan nan\n" * 20, "cloud is empty.*20 of 20 points were NaN/inf"),
        ("empty.xyz", b"# nothing\n", "no points"),
        ("two.xyz", b"1 2\n3 4\n", "at least 3 columns"),
        ("few.xyz", b"0 0 0\n0 0 1\n", "2 points; at least 10"),
        ("same.xyz", b"0.1 0.2 0.3\n" * 30, "identical"),
        ("trunc.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 50\nproperty float x\n"
                      b"property float y\nproperty float z\nend_header\n" + b"\x00" * 40, "truncated binary PLY"),
        ("novert.ply", b"ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no vertex element"),
        ("x.obj", b"v 0 0 0\n", "unknown point cloud format '.obj'"),
    ],
)
def test_bad_files_raise_clear_errors(tmp_path, name, content, message):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(PointCloudError, match=message) as err:
        read_point_cloud(tmp_path / name)
    assert name in str(err.value) and isinstance(err.value, GraspsimError)


def test_missing_file_and_bad_npy(tmp_path):
    with pytest.raises(PointCloudError, match="does not exist"):
        read_point_cloud(tmp_path / "absent.pcd")
    np.save(tmp_path / "flat.npy", np.zeros((10, 2)))
    with pytest.raises(PointCloudError, match=r"\(N, 3\) array"):
        read_point_cloud(tmp_path / "flat.npy")


def test_check_cloud_rejects_degenerate_arrays():
    with pytest.raises(PointCloudError, match="empty"):
        check_cloud(np.zeros((0, 3)))
    with pytest.raises(PointCloudError, match="NaN"):
        check_cloud(np.full((20, 3), np.nan))
    with pytest.raises(PointCloudError, match="shape"):
        check_cloud(np.zeros((20, 4)))
    with pytest.raises(PointCloudError, match="identical"):
        check_cloud(np.ones((20, 3)))
    assert check_cloud(PTS).dtype == np.float64
