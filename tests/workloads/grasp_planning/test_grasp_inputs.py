"""Depth images at the edge (files, ROS buffers) and the container recipe."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fogiac.errors import WorkloadError
from workloads.grasp_planning.container import DEFAULTS, dockerfile
from workloads.grasp_planning.inputs import depth_from_array, depth_from_buffer, load_depth_file


def test_uint16_is_millimetres_and_bad_values_become_holes() -> None:
    mm = np.full((20, 20), 700, dtype=np.uint16)
    assert depth_from_array(mm, source="x")[0, 0] == pytest.approx(0.7)
    f = np.full((20, 20), 0.7, dtype=np.float64)
    f[0, 0], f[0, 1] = np.nan, -1.0
    d = depth_from_array(f, source="x")
    assert d.dtype == np.float32 and d[0, 0] == 0.0 and d[0, 1] == 0.0


def test_bad_arrays_are_named_in_one_line() -> None:
    with pytest.raises(WorkloadError, match=r"^x: depth must be a 2-D array \(H, W\) with both sides >= 16, got shape \(3, 20, 20\)$"):
        depth_from_array(np.zeros((3, 20, 20), dtype=np.float32), source="x")
    with pytest.raises(WorkloadError, match=r"^x: depth must be float metres or uint16 millimetres, got dtype int64$"):
        depth_from_array(np.zeros((20, 20), dtype=np.int64), source="x")
    with pytest.raises(WorkloadError, match=r"^x: depth image has no valid \(positive, finite\) pixels$"):
        depth_from_array(np.zeros((20, 20), dtype=np.float32), source="x")


def test_files(tmp_path: Path) -> None:
    with pytest.raises(WorkloadError, match=r"nope\.npy: no such file$"):
        load_depth_file(tmp_path / "nope.npy")
    junk = tmp_path / "junk.npy"
    junk.write_text("not numpy")
    with pytest.raises(WorkloadError, match=r"junk\.npy: not a \.npy array"):
        load_depth_file(junk)
    good = tmp_path / "d.npy"
    np.save(good, np.full((32, 48), 600, dtype=np.uint16))
    assert load_depth_file(good).shape == (32, 48)


@pytest.mark.parametrize("big_endian", [False, True])
def test_ros_buffers_in_both_encodings_with_row_padding(big_endian: bool) -> None:
    depth = np.linspace(0.5, 0.9, 16 * 20, dtype=np.float32).reshape(16, 20)
    order = ">" if big_endian else "<"
    for encoding, arr, tol in (("32FC1", depth.astype(order + "f4"), 1e-7), ("16UC1", np.round(depth * 1000).astype(order + "u2"), 1e-3)):
        row = arr.tobytes()
        step = arr.shape[1] * arr.itemsize + 8  # padded rows, as some drivers send
        data = b"".join(row[i * arr.shape[1] * arr.itemsize : (i + 1) * arr.shape[1] * arr.itemsize] + b"\0" * 8 for i in range(16))
        out = depth_from_buffer(data, encoding=encoding, height=16, width=20, step=step, big_endian=big_endian, source="img")
        np.testing.assert_allclose(out, depth, atol=tol)


def test_ros_buffer_errors() -> None:
    with pytest.raises(WorkloadError, match=r"^img: unsupported depth encoding 'rgb8'; use one of 32FC1, 16UC1, mono16$"):
        depth_from_buffer(b"", encoding="rgb8", height=16, width=16, step=48, big_endian=False, source="img")
    with pytest.raises(WorkloadError, match=r"^img: 10 bytes do not hold 16 rows of step 64 for 16 x 32FC1$"):
        depth_from_buffer(b"0" * 10, encoding="32FC1", height=16, width=16, step=64, big_endian=False, source="img")


def test_dockerfile_renders_on_a_cuda_base_with_torch_pinned() -> None:
    text = dockerfile()
    assert text.startswith(f"FROM {DEFAULTS['base_image']}\n") and "nvidia/cuda:" in text
    assert "torch==2.13.0" in text and "python3-rospy" in text
    assert '"workloads.grasp_planning", "node", "_device:=auto"' in text
    pinned = dockerfile(torch_index_url="https://download.pytorch.org/whl/cu128", device="cuda")
    assert "--index-url https://download.pytorch.org/whl/cu128 torch==2.13.0" in pinned
    assert '"_device:=cuda"' in pinned
    with pytest.raises(WorkloadError, match=r"^unknown Dockerfile variables gpu; valid: "):
        dockerfile(gpu=True)


def test_torch_goes_into_a_venv_that_sees_the_systems_rospy() -> None:
    """Debian's pip refuses installs into the system's Python (PEP 668): torch lives in /opt/venv."""
    from workloads.grasp_planning.container import FLAVOURS

    text = dockerfile(**FLAVOURS["debian"])
    assert text.startswith("FROM ros:noetic-ros-core\n") and "apt-get" not in text
    assert "RUN --mount=type=secret,id=pip.conf export PIP_CONFIG_FILE=/run/secrets/pip.conf \\\n" \
           " && python3 -m venv --system-site-packages /opt/venv \\\n && /opt/venv/bin/pip install --no-cache-dir " \
           "torch==2.13.0\n" in text
    assert "PATH=/opt/venv/bin:$PATH" in text and "python3 -m pip" not in text
    assert 'CMD ["python", "-m", "workloads.grasp_planning", "node", "_device:=cpu"' in text


def test_devices_are_checked_before_use() -> None:
    import torch

    from workloads.grasp_planning.planner import pick_device

    assert pick_device("cpu") == torch.device("cpu")
    assert pick_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(WorkloadError, match=r"^unknown device 'tpu7'; use auto, cpu, cuda or cuda:N$"):
        pick_device("tpu7")
    if not torch.cuda.is_available():
        with pytest.raises(WorkloadError, match=r"^device 'cuda' asked for, but torch sees no CUDA GPU here$"):
            pick_device("cuda")


def test_model_files_are_checked(tmp_path: Path) -> None:
    from workloads.grasp_planning.planner import load_model

    with pytest.raises(WorkloadError, match=r"none\.pt: no such model file$"):
        load_model(tmp_path / "none.pt")
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a zip")
    with pytest.raises(WorkloadError, match=r"junk\.pt: not a grasp_planning model \("):
        load_model(junk)
