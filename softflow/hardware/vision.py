"""Synthetic RGB-D camera and OpenCV tracking of the red ball on the rod's tip.

The paper measures the hardware tip with an RGB-D camera that follows a red ball
marker. ``render`` makes the frames such a camera (an Intel RealSense D435i, depth
aligned to colour) would record; ``track`` recovers the marker's 3-D path from the
frames alone, so the same code runs on a real recording. ``observe`` chains both for
simulated runs; ``stroboscope`` makes the multi-exposure pictures of fast motions.

Camera model: pinhole without distortion (rectified streams), pixel centres at
integer coordinates as in OpenCV; a robot-frame point X is R (X - C) in the camera
frame (x right, y down, z along the optical axis), depth is that z.

Recording format (``write_rgbd``/``read_rgbd``): one zip of .npy members, readable
with ``np.load``, with keys
  times (K,) float64 s; color (K, H, W, 3) uint8 BGR; depth (K, H, W) uint16 in units
  of depth_scale (RealSense z16: mm), 0 = no return, aligned to colour; and the
  Camera fields: rotation (3, 3), position (3,) m, width, height, fx, fy, cx, cy px,
  fps Hz, depth_noise, pixel_noise, depth_scale.
To convert a RealSense bag: align depth to colour, take the colour intrinsics, and
the camera pose in the robot frame (e.g. from a checkerboard at the base).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import itertools
import math
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.interpolate import make_interp_spline

from softflow.checks import as_real_array
from softflow.store import atomic_write

_WALL = (200, 205, 210)  # BGR of the light background wall
_ROD = (60, 60, 60)  # BGR of the dark-grey rod
_MARKER = np.array([30.0, 30.0, 200.0])  # BGR of the fully lit red ball
_LIGHT = np.array([-0.2, -0.3, -1.0]) / np.linalg.norm(
    [-0.2, -0.3, -1.0]
)  # unit vector towards the light, camera frame
_WALL_GAP = 0.3  # m, wall behind the farthest point drawn
_SUPERSAMPLE = 4  # samples per pixel side on the marker (anti-aliased, sub-pixel edge)
_RED = (((0, 90, 40), (10, 255, 255)), ((170, 90, 40), (179, 255, 255)))  # OpenCV HSV bands
_CORE = 0.7  # fraction of the marker's image radius whose depth pixels are used


@dataclass(frozen=True)
class Camera:
    """Pinhole RGB-D camera; defaults are the D435 colour stream at 640x480, 30 Hz."""

    rotation: tuple  # (3, 3): rows are the camera axes x, y, z in the robot frame (R)
    position: tuple  # (3,) m, camera centre in the robot frame (C)
    width: int = 640  # px
    height: int = 480  # px
    fx: float = 615.0  # px
    fy: float = 615.0  # px
    cx: float = 320.0  # px
    cy: float = 240.0  # px
    fps: float = 30.0  # Hz
    depth_noise: float = 0.0015  # m, depth noise std at 1 m, growing as Z^2 (stereo)
    pixel_noise: float = 3.0  # colour noise std, 0-255 units
    depth_scale: float = 0.001  # m per depth unit

    def __post_init__(self):
        rotation, _ = as_real_array(self.rotation, "rotation", (3, 3))
        if not (np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) and np.linalg.det(rotation) > 0):
            raise ValueError(f"rotation must be orthonormal with determinant +1; got {rotation.tolist()}")
        object.__setattr__(self, "rotation", tuple(map(tuple, rotation.tolist())))
        object.__setattr__(self, "position", tuple(as_real_array(self.position, "position", (3,))[0].tolist()))
        for name in ("width", "height"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value > 0):
                raise ValueError(f"{name} must be an integer > 0 (px); got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("fx", "fy", "cx", "cy", "fps", "depth_noise", "pixel_noise", "depth_scale"):
            zero_ok = name in ("cx", "cy", "depth_noise", "pixel_noise")
            object.__setattr__(self, name, _check_number(getattr(self, name), name, zero_ok=zero_ok))

    @property
    def R(self) -> np.ndarray:  # (3, 3), robot frame -> camera frame
        return np.array(self.rotation)

    @property
    def C(self) -> np.ndarray:  # (3,) m
        return np.array(self.position)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Robot-frame points (N, 3) -> pixels (N, 2) and depths (N,) m; NaN pixels at or behind the camera."""
        points, _ = as_real_array(points, "points", (None, 3))
        camera_points = (points - self.C) @ self.R.T  # (N, 3)
        normalized = np.full((len(points), 2), np.nan)
        np.divide(camera_points[:, :2], camera_points[:, 2:], out=normalized, where=camera_points[:, 2:] > 0)
        return normalized * [self.fx, self.fy] + [self.cx, self.cy], camera_points[:, 2]

    def deproject(self, pixels, depth) -> np.ndarray:
        """Pixels (N, 2) and depths (N,) m -> robot-frame points (N, 3); the inverse of ``project``."""
        pixels, _ = as_real_array(pixels, "pixels", (None, 2))
        depth, _ = as_real_array(depth, "depth", (len(pixels),))
        normalized = (pixels - [self.cx, self.cy]) / [self.fx, self.fy]
        return np.column_stack([normalized * depth[:, None], depth]) @ self.R + self.C


def camera_facing(target, distance: float = 0.4, **kwargs) -> Camera:
    """Camera at ``target + distance * x`` looking back along -x: image right = +y, image down = -z."""
    target, _ = as_real_array(target, "target", (3,))
    _check_number(distance, "distance")
    rotation = ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0), (-1.0, 0.0, 0.0))
    return Camera(rotation=rotation, position=tuple(target + [distance, 0.0, 0.0]), **kwargs)


def render(
    positions, camera: Camera, rng, *, marker_radius: float = 0.01, centerlines=None, rod_diameter: float | None = None
):
    """Lazily yield one (color (H, W, 3) uint8 BGR, depth (H, W) uint16) frame per marker centre (N, 3).

    ``centerlines`` (N, P, 3) adds the rod as a dark-grey polyline, painted before the
    ball. The wall faces the camera 0.3 m behind the farthest point drawn. The ball is
    ray-traced exactly (perspective): colour supersampled 4x4 per pixel and shaded by a
    light near the camera, depth the first hit at each pixel centre. Noise: Gaussian on
    colour (std ``pixel_noise``) and depth (std ``depth_noise`` Z^2), then rounding.
    ``rng`` is a numpy Generator or a seed.
    """
    positions, _ = as_real_array(positions, "positions", (None, 3))
    if centerlines is not None:
        centerlines, _ = as_real_array(centerlines, "centerlines", (len(positions), None, 3))
    _check_number(marker_radius, "marker_radius")
    drawn = positions if centerlines is None else np.concatenate([positions, centerlines.reshape(-1, 3)])
    wall = camera.project(drawn)[1].max(initial=0.0) + marker_radius + _WALL_GAP  # m
    if centerlines is not None and not (rod_diameter is not None and rod_diameter > 0):
        raise ValueError(f"drawing centerlines needs the rod's diameter rod_diameter > 0 (m); got {rod_diameter!r}")
    return _frames(positions, centerlines, camera, np.random.default_rng(rng), marker_radius, wall, rod_diameter)


def _frames(positions, centerlines, camera, rng, radius, wall, rod_diameter):
    wall_color = np.full((camera.height, camera.width, 3), _WALL, np.uint8)
    for k, centre in enumerate(positions):
        color = wall_color.copy()
        depth = np.full((camera.height, camera.width), wall, np.float32)  # m
        if centerlines is not None:
            _draw_rod(color, depth, centerlines[k], camera, rod_diameter)
        color = color.astype(np.float32)
        _draw_marker(color, depth, centre, camera, radius)
        color += camera.pixel_noise * rng.standard_normal(color.shape, np.float32)
        depth += camera.depth_noise * depth**2 * rng.standard_normal(depth.shape, np.float32)
        np.rint(color, out=color)  # in place: half the time of the copies, the same pixels
        yield (
            np.clip(color, 0, 255, out=color).astype(np.uint8),
            np.clip(np.rint(depth / camera.depth_scale), 0, 65535).astype(np.uint16),
        )


def _draw_rod(color, depth, centerline, camera, diameter):
    """Far segments first; colour anti-aliased, depth each segment's mean depth."""
    pixels, z = camera.project(centerline)
    ends = np.rint(np.nan_to_num(pixels) * 16).astype(np.int64)  # 4 fractional bits for cv2 shift=4
    drawable = np.all(np.abs(pixels) < 1e6, axis=1)  # in front of the camera, not near its plane
    segment_depth = (z[:-1] + z[1:]) / 2
    for k in np.argsort(-segment_depth):
        if drawable[k] and drawable[k + 1]:
            a, b = tuple(ends[k].tolist()), tuple(ends[k + 1].tolist())
            thickness = max(1, round(camera.fx * diameter / segment_depth[k]))
            cv2.line(color, a, b, _ROD, thickness, cv2.LINE_AA, shift=4)
            cv2.line(depth, a, b, float(segment_depth[k]), thickness, cv2.LINE_8, shift=4)


def _ray_sphere(x, y, centre, radius):
    """Depth (...) of the first hit of the rays (x, y, 1) with a sphere (NaN: miss) and unit normals (..., 3)."""
    rays = np.stack([x, y, np.ones_like(x)], -1)
    a, b = (rays**2).sum(-1), rays @ centre
    disc = b**2 - a * (centre @ centre - radius**2)
    t = np.where(disc > 0, (b - np.sqrt(np.maximum(disc, 0.0))) / a, np.nan)
    return t, (t[..., None] * rays - centre) / radius


def _draw_marker(color, depth, centre, camera, radius):
    """Blend the shaded ball into ``color`` (float) by its sub-pixel coverage; set its depth (m)."""
    centre = camera.R @ (centre - camera.C)  # camera frame
    if centre[2] <= radius:
        return  # the ball is behind the camera or around it
    corners = centre + radius * np.array(list(itertools.product((-1.0, 1.0), repeat=3)))  # (8, 3), bound the ball
    corners = corners[:, :2] / corners[:, 2:] * [camera.fx, camera.fy] + [camera.cx, camera.cy]  # px
    x0, y0 = np.maximum(np.floor(corners.min(0)).astype(int) - 1, 0)
    x1, y1 = np.minimum(np.ceil(corners.max(0)).astype(int) + 2, [camera.width, camera.height])
    if x0 >= x1 or y0 >= y1:
        return
    us, vs = np.meshgrid(np.arange(x0, x1, dtype=float), np.arange(y0, y1, dtype=float))  # (h, w)
    offsets = (np.arange(_SUPERSAMPLE) + 0.5) / _SUPERSAMPLE - 0.5
    su, sv = us[..., None] + np.tile(offsets, _SUPERSAMPLE), vs[..., None] + np.repeat(offsets, _SUPERSAMPLE)
    t, normal = _ray_sphere((su - camera.cx) / camera.fx, (sv - camera.cy) / camera.fy, centre, radius)
    lit = np.where(np.isfinite(t), 0.3 + 0.7 * np.clip(normal @ _LIGHT, 0.0, None), 0.0)  # (h, w, S^2)
    box = color[y0:y1, x0:x1]
    box *= 1 - np.isfinite(t).mean(-1, keepdims=True)
    box += lit.mean(-1, keepdims=True) * _MARKER
    t, _ = _ray_sphere((us - camera.cx) / camera.fx, (vs - camera.cy) / camera.fy, centre, radius)
    depth[y0:y1, x0:x1] = np.where(np.isfinite(t), t, depth[y0:y1, x0:x1])


def track(frames, camera: Camera, *, marker_radius: float = 0.01) -> np.ndarray:
    """Marker centres (N, 3) in the robot frame from an iterable of (color, depth) frames.

    Per frame: HSV threshold of both red hue bands, opening and closing, the largest
    blob and its pixel centroid. A blob touching the image border (biased centroid) or
    no blob gives a NaN row. Centre depth: a pixel's ray r (r_z = 1) meets the sphere
    at depth z, so the centre s r_c on the centroid ray satisfies |z r - s r_c| = R:
        s = (z r.r_c + sqrt(|r_c|^2 R^2 - z^2 |r x r_c|^2)) / |r_c|^2.
    The median of s over the blob's core (inner 70 % of its radius, away from mixed edge
    pixels) is the centre depth. Unlike the median depth plus a fixed cap offset, it is
    not stuck to the 1 mm depth steps.
    """
    _check_number(marker_radius, "marker_radius")
    return np.array(
        [_locate(k, color, depth, camera, marker_radius) for k, (color, depth) in enumerate(frames)]
    ).reshape(-1, 3)


def _locate(index, color, depth, camera, radius):
    _check_frame(index, color, depth, camera)
    hsv = cv2.cvtColor(color, cv2.COLOR_BGR2HSV)
    mask = cv2.bitwise_or(*(cv2.inRange(hsv, low, high) for low, high in _RED))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    mask = cv2.morphologyEx(cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel), cv2.MORPH_CLOSE, kernel)
    count, labels, stats, centroids = cv2.connectedComponentsWithStats(mask)
    if count == 1:
        return np.full(3, np.nan)
    best = 1 + np.argmax(stats[1:, cv2.CC_STAT_AREA])
    left, top, width, height, area = stats[best]
    if left == 0 or top == 0 or left + width == camera.width or top + height == camera.height:
        return np.full(3, np.nan)
    rows, cols = np.nonzero(labels[top : top + height, left : left + width] == best)
    rows, cols = rows + top, cols + left
    core = np.hypot(cols - centroids[best, 0], rows - centroids[best, 1]) < _CORE * math.sqrt(area / math.pi)
    rows, cols = rows[core], cols[core]
    z = depth[rows, cols] * camera.depth_scale  # m
    rays = np.column_stack([(cols - camera.cx) / camera.fx, (rows - camera.cy) / camera.fy, np.ones(len(z))])
    ray_c = np.array([(centroids[best, 0] - camera.cx) / camera.fx, (centroids[best, 1] - camera.cy) / camera.fy, 1.0])
    disc = (ray_c @ ray_c) * radius**2 - z**2 * (np.cross(rays, ray_c) ** 2).sum(-1)
    valid = (z > 0) & (disc > 0)
    if not valid.any():
        return np.full(3, np.nan)
    centre_depth = np.median((z * (rays @ ray_c) + np.sqrt(np.maximum(disc, 0.0)))[valid]) / (ray_c @ ray_c)
    return camera.deproject(centroids[best][None], [centre_depth])[0]


def observe(
    times,
    positions,
    camera: Camera,
    rng,
    *,
    centerlines=None,
    marker_radius: float = 0.01,
    rod_diameter: float | None = None,
):
    """Film a simulated run and track it: (frame times (K,), tracked marker centres (K, 3)).

    Frames are taken at t_k = times[0] + k / fps inside [times[0], times[-1]]; positions
    (T, 3) and centerlines (T, P, 3) are linearly interpolated to them.
    """
    times, _ = as_real_array(times, "times", (None,))
    if len(times) < 2 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must be strictly increasing with at least 2 samples; got {len(times)} samples")
    positions, _ = as_real_array(positions, "positions", (len(times), 3))
    frame_times = times[0] + np.arange(math.floor((times[-1] - times[0]) * camera.fps + 1e-9) + 1) / camera.fps
    if centerlines is not None:
        centerlines, _ = as_real_array(centerlines, "centerlines", (len(times), None, 3))
        centerlines = make_interp_spline(times, centerlines, k=1, axis=0)(frame_times)
    positions = make_interp_spline(times, positions, k=1, axis=0)(frame_times)
    frames = render(
        positions, camera, rng, marker_radius=marker_radius, centerlines=centerlines, rod_diameter=rod_diameter
    )
    return frame_times, track(frames, camera, marker_radius=marker_radius)


def stroboscope(frames, every: int, *, alpha: float = 0.8, threshold: float = 40.0) -> np.ndarray:
    """Multi-exposure picture (H, W, 3) uint8 of every ``every``-th colour frame of ``frames``.

    The background is the per-pixel median of the chosen frames (the robot moves, the
    scene does not). In time order, each chosen frame is blended with weight ``alpha``
    into the pixels where it differs from the background by more than ``threshold``
    (0-255, any channel): later poses lie on top, overlaps stay visible. Only the chosen
    frames are held in memory; pass colour frames, e.g. ``(c for c, _ in render(...))``.
    """
    if not (isinstance(every, (int, np.integer)) and every >= 1):
        raise ValueError(f"every must be an integer >= 1; got {every!r}")
    if not 0 < alpha <= 1:
        raise ValueError(f"alpha must be in (0, 1]; got {alpha!r}")
    _check_number(threshold, "threshold")
    chosen = np.stack(list(itertools.islice(frames, 0, None, every)))  # (F, H, W, 3)
    if chosen.dtype != np.uint8 or chosen.ndim != 4 or chosen.shape[-1] != 3:
        raise ValueError(f"frames must be (H, W, 3) uint8 colour images; got {chosen.dtype} {chosen.shape[1:]}")
    background = np.median(chosen, axis=0)
    picture = background.copy()
    for frame in chosen:
        moved = np.abs(frame - background).max(-1) > threshold
        picture[moved] += alpha * (frame[moved] - picture[moved])
    return np.rint(picture).astype(np.uint8)


_CAMERA_KEYS = tuple(field.name for field in dataclasses.fields(Camera))
_DEPTH = np.dtype("<u2")  # depth on disk: little-endian uint16


def write_rgbd(path, times, frames, camera: Camera) -> None:
    """Save a recording (format: module docstring) from an iterable of (color, depth) frames.

    Frames are streamed to disk, never all in memory; the file appears only when
    complete (``store.atomic_write``).
    """
    times, _ = as_real_array(times, "times", (None,))
    shape = (len(times), camera.height, camera.width)
    with (
        atomic_write(path) as f,
        zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as archive,
        tempfile.TemporaryFile() as depths,
    ):
        for name in ("times", *_CAMERA_KEYS):
            with archive.open(f"{name}.npy", "w") as member:
                np.lib.format.write_array(member, np.asarray(times if name == "times" else getattr(camera, name)))
        count = 0
        with archive.open("color.npy", "w", force_zip64=True) as member:
            _write_header(member, np.uint8, shape + (3,))
            for count, (color, depth) in enumerate(itertools.islice(frames, len(times) + 1), 1):
                _check_frame(count - 1, color, depth, camera)
                member.write(color.tobytes())
                depths.write(depth.astype(_DEPTH).tobytes())
        if count != len(times):
            raise ValueError(
                f"frames must number len(times) = {len(times)}; got {'more' if count > len(times) else count}"
            )
        depths.seek(0)
        with archive.open("depth.npy", "w", force_zip64=True) as member:
            _write_header(member, _DEPTH, shape)
            shutil.copyfileobj(depths, member)


def read_rgbd(path):
    """Open a recording: (times (K,), frames, camera). ``frames`` has len K and reads the
    (color, depth) pairs from disk one at a time, anew on each iteration."""
    try:
        with zipfile.ZipFile(path) as archive:
            missing = {"times", "color", "depth", *_CAMERA_KEYS} - {
                name.removesuffix(".npy") for name in archive.namelist()
            }
            if missing:
                raise ValueError(f"missing keys {sorted(missing)}")
            fields = {name: np.load(io.BytesIO(archive.read(f"{name}.npy")))[()] for name in ("times", *_CAMERA_KEYS)}
        times, _ = as_real_array(fields.pop("times"), "times", (None,))
        camera = Camera(**fields)
        frames = _Frames(os.fspath(path), len(times), (camera.height, camera.width))
        with frames.open():  # checks the frame arrays' headers
            pass
    except FileNotFoundError:
        raise
    except Exception as exc:  # whatever fails to parse
        raise ValueError(f"{path} is not a valid RGB-D recording: {exc}") from exc
    return times, frames, camera


class _Frames:
    """(color, depth) pairs of a recording on disk, decompressed one frame at a time."""

    def __init__(self, path, count, shape):
        self.path, self.count, self.shape = path, count, shape

    def __len__(self):
        return self.count

    def __iter__(self):
        try:
            with self.open() as (color, depth):
                for _ in range(self.count):
                    yield (
                        _read_frame(color, np.dtype(np.uint8), self.shape + (3,)),
                        _read_frame(depth, _DEPTH, self.shape),
                    )
        except Exception as exc:
            raise ValueError(f"{self.path} is not a valid RGB-D recording: {exc}") from exc

    @contextlib.contextmanager
    def open(self):
        """The color and depth members, positioned at their first frame."""
        with (
            zipfile.ZipFile(self.path) as archive,
            archive.open("color.npy") as color,
            archive.open("depth.npy") as depth,
        ):
            read_header = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
            for member, dtype, shape in ((color, np.uint8, self.shape + (3,)), (depth, _DEPTH, self.shape)):
                expected = ((self.count, *shape), False, np.dtype(dtype))  # (shape, fortran_order, dtype)
                if read_header[np.lib.format.read_magic(member)](member) != expected:
                    raise ValueError(
                        f"{member.name} must hold a C-ordered {np.dtype(dtype)} array of shape {expected[0]}"
                    )
            yield color, depth


def _write_header(member, dtype, shape):
    np.lib.format.write_array_header_1_0(member, {"descr": np.dtype(dtype).str, "fortran_order": False, "shape": shape})


def _read_frame(member, dtype, shape):
    data = member.read(math.prod(shape) * dtype.itemsize)
    if len(data) != math.prod(shape) * dtype.itemsize:
        raise ValueError("the file ends early")
    return np.frombuffer(data, dtype).reshape(shape).astype(dtype.newbyteorder("="))  # a writable, native copy


def _check_frame(index, color, depth, camera):
    size = (camera.height, camera.width)
    for name, image, dtype, shape in (("color", color, np.uint8, size + (3,)), ("depth", depth, np.uint16, size)):
        if not (isinstance(image, np.ndarray) and image.dtype == dtype and image.shape == shape):
            got = f"{image.dtype} {image.shape}" if isinstance(image, np.ndarray) else type(image).__name__
            raise ValueError(f"frame {index}: {name} must be a {np.dtype(dtype)} array of shape {shape}; got {got}")


def _check_number(value, name, *, zero_ok=False) -> float:
    """``value`` as a float, checked finite and > 0 (>= 0 with ``zero_ok``)."""
    if not (
        isinstance(value, (int, float, np.integer, np.floating))
        and math.isfinite(value)
        and (value > 0 or zero_ok and value == 0)
    ):
        raise ValueError(f"{name} must be a finite number {'>= 0' if zero_ok else '> 0'}; got {value!r}")
    return float(value)
