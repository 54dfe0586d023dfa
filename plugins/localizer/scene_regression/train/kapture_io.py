"""The kapture files the training recipes read (text, kapture 1.1): cameras,
camera records, trajectories (rigs composed), depth records. Plain Python +
numpy + PIL so the recipes need nothing beyond Debian's python3-torch,
python3-numpy and python3-pil."""
import os

import numpy as np
from PIL import Image


def _rows(path):
    """Non-comment CSV rows of a kapture text file, stripped; (line number, fields)."""
    with open(path) as f:
        for number, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            yield number, [x.strip() for x in line.split(",")]


def _quat_to_matrix(qw, qx, qy, qz):
    q = np.array([qw, qx, qy, qz], dtype=np.float64)
    n = np.linalg.norm(q)
    if n < 1e-12:
        raise ValueError("zero quaternion")
    w, x, y, z = q / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(R):
    """(w, x, y, z), w >= 0."""
    t = np.trace(R)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q if q[0] >= 0 else -q


def _pose(fields, path, number):
    """T_device_world (4x4) from qw qx qy qz tx ty tz."""
    try:
        v = [float(x) for x in fields]
    except ValueError:
        raise ValueError(f"{path}:{number}: pose: expected 7 numbers")
    T = np.eye(4)
    T[:3, :3] = _quat_to_matrix(*v[:4])
    T[:3, 3] = v[4:7]
    return T


class Camera:
    """Pinhole-family camera of sensors.txt (radial terms of SIMPLE_RADIAL,
    RADIAL and OPENCV are honoured when unprojecting)."""

    def __init__(self, model, width, height, params, where):
        self.model, self.width, self.height = model, int(width), int(height)
        p = [float(x) for x in params]
        self.k = [0.0, 0.0, 0.0, 0.0]  # k1, k2, p1, p2
        if model == "SIMPLE_PINHOLE":
            self.fx = self.fy = p[0]; self.cx, self.cy = p[1], p[2]
        elif model == "PINHOLE":
            self.fx, self.fy, self.cx, self.cy = p[:4]
        elif model == "SIMPLE_RADIAL":
            self.fx = self.fy = p[0]; self.cx, self.cy = p[1], p[2]; self.k[0] = p[3]
        elif model == "RADIAL":
            self.fx = self.fy = p[0]; self.cx, self.cy = p[1], p[2]; self.k[:2] = p[3:5]
        elif model == "OPENCV":
            self.fx, self.fy, self.cx, self.cy = p[:4]; self.k = p[4:8]
        else:
            raise ValueError(f"{where}: camera model {model} not supported by the training recipes")

    def unproject(self, u, v):
        """Pixels (SDK convention, first pixel centre at 0.5, as kapture/COLMAP) to
        z = 1 rays, undistorted by fixed-point iterations."""
        x0 = (u - self.cx) / self.fx
        y0 = (v - self.cy) / self.fy
        x, y = x0.copy(), y0.copy()
        k1, k2, p1, p2 = self.k
        if any(self.k):
            for _ in range(20):
                r2 = x * x + y * y
                radial = 1 + k1 * r2 + k2 * r2 * r2
                dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
                dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
                x = (x0 - dx) / radial
                y = (y0 - dy) / radial
        return np.stack([x, y, np.ones_like(x)], axis=-1)


class Kapture:
    def __init__(self, root):
        self.root = root
        sensors = os.path.join(root, "sensors")
        self.cameras = {}
        for n, f in _rows(os.path.join(sensors, "sensors.txt")):
            if len(f) >= 4 and f[2] in ("camera", "depth"):
                self.cameras[f[0]] = Camera(f[3], f[4], f[5], f[6:], f"sensors.txt:{n}")
        self.rigs = {}  # rig -> sensor -> T_sensor_rig
        rigs = os.path.join(sensors, "rigs.txt")
        if os.path.exists(rigs):
            for n, f in _rows(rigs):
                self.rigs.setdefault(f[0], {})[f[1]] = _pose(f[2:9], rigs, n)
        self.records = []  # (timestamp, camera, image path)
        for n, f in _rows(os.path.join(sensors, "records_camera.txt")):
            self.records.append((int(f[0]), f[1], f[2]))
        self.trajectories = {}
        trajectories = os.path.join(sensors, "trajectories.txt")
        if os.path.exists(trajectories):
            for n, f in _rows(trajectories):
                self.trajectories[(int(f[0]), f[1])] = _pose(f[2:9], trajectories, n)

    def camera_pose(self, timestamp, camera):
        """T_camera_world, or None: the camera's own pose, else its rig's."""
        T = self.trajectories.get((timestamp, camera))
        if T is not None:
            return T
        for rig, sensors in self.rigs.items():
            if camera in sensors and (timestamp, rig) in self.trajectories:
                return sensors[camera] @ self.trajectories[(timestamp, rig)]
        return None

    def image_file(self, path):
        return os.path.join(self.root, "sensors", "records_data", path)

    def posed_images(self, include=None):
        """[(timestamp, camera, path, T_camera_world)] of the images with a pose."""
        import re
        out = []
        for t, cam, path in self.records:
            if include and not re.search(include, path):
                continue
            T = self.camera_pose(t, cam)
            if T is not None:
                out.append((t, cam, path, T))
        return out


def read_depth_records(root):
    """{(timestamp, camera): depth file} from records_depth.txt (gt/lidar_depth's
    depth sensors are named <camera>_depth)."""
    out = {}
    path = os.path.join(root, "sensors", "records_depth.txt")
    for n, f in _rows(path):
        camera = f[1][:-len("_depth")] if f[1].endswith("_depth") else f[1]
        out[(int(f[0]), camera)] = os.path.join(root, "sensors", "records_data", f[2])
    return out


def read_depth(path, width, height):
    d = np.fromfile(path, dtype="<f4")
    if d.size != width * height:
        raise ValueError(f"{path}: {d.size} values, expected {width}x{height}")
    return d.reshape(height, width)


def load_image(path, width, height):
    """RGB uint8 HxWx3 resized to width x height (area filter, as the C++ stage)."""
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB").resize((width, height), Image.BOX))


def normalise(rgb, mean=(123.675, 116.28, 103.53), std=(58.395, 57.12, 57.375)):
    """HxWx3 uint8 -> 3xHxW float32 as localizer/posenet|esac's defaults."""
    x = (rgb.astype(np.float32) - np.array(mean, np.float32)) / np.array(std, np.float32)
    return np.ascontiguousarray(x.transpose(2, 0, 1))
