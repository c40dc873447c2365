"""The kerf in the video as it is cut: what is left of the cutter's voxel foam, drawn each frame.

The plate's kerf-band geoms (``model.scene.KERF_BAND``) are one static box each: drawn, they
look the same before and after the cut. The video hides them and draws instead the voxels of
the cutter's grid (``FoamGrid.material``) that lie in the band's columns, as boxes added to
the frame's ``MjvScene`` (``mujoco.mjv_initGeom``, the way the interactive viewer draws user
geoms). Removed voxels leave a slot through the plate where the cutter has been.

The simulation sends the band's voxels with each frame (``KerfVoxels.snapshot``: the band's
voxels packed to bits, ~1.4 kB for the default plate's 1,100 columns × 10 layers); the render
worker turns them into boxes (``boxes``): columns with the same layers merged into rectangles,
so the uncut band is two boxes and the default run never needs more than 9 (measured every
0.5 s of simulated time, docs/video.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np


class KerfVoxels:
    """Which voxels of a ``FoamGrid`` the video draws (the kerf band's columns) and how.

    Pickled into each render worker (arrays only). ``lo``/``h``: the grid's corner and voxel
    size (m); ``window``: (i0, i1, j0, j1), the band's columns' bounding index window;
    ``columns``: which columns of the window belong to the band; ``rgba``: their colour.
    """

    def __init__(self, lo: np.ndarray, h: np.ndarray, window: tuple[int, int, int, int], columns: np.ndarray,
                 nz: int, rgba: np.ndarray, band_geoms: tuple[str, ...] = ()) -> None:
        if nz > 62:
            raise ValueError(f"foam grid: at most 62 voxel layers can be drawn (got {nz})")
        self.lo, self.h = np.asarray(lo, float), np.asarray(h, float)
        self.window = window
        self.columns = np.asarray(columns, bool)
        self.nz = int(nz)
        self.rgba = np.asarray(rgba, np.float32)
        self.band_geoms = band_geoms  # the static geoms this drawing replaces (hidden in the video)
        self._layer_bits = np.left_shift(np.int64(1), np.arange(self.nz, dtype=np.int64))
        self._runs: dict[int, list[tuple[int, int]]] = {}

    @classmethod
    def from_model(cls, model: Any, grid: Any) -> KerfVoxels | None:
        """The band's voxels of ``grid`` (a ``FoamGrid``) in a scene built by ``model.scene``;
        None where the model has no kerf band or the band misses the grid."""
        import mujoco

        from .model.scene import KERF_BAND  # (here: the render workers need not import the scene builder)

        band = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) for name in KERF_BAND]
        band = [g for g in band if g >= 0]
        if not band:
            return None
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # the plate is static: its geoms' world boxes at qpos0
        gx, gy = np.meshgrid(grid.centres[0], grid.centres[1], indexing="ij")
        inside = np.zeros(grid.shape[:2], bool)
        for g in band:
            half = np.abs(data.geom_xmat[g].reshape(3, 3)) @ model.geom_size[g]  # axis-aligned extent
            centre = data.geom_xpos[g]
            inside |= (np.abs(gx - centre[0]) <= half[0]) & (np.abs(gy - centre[1]) <= half[1])
        if not inside.any():
            return None
        i, j = np.nonzero(inside)
        window = (int(i.min()), int(i.max()) + 1, int(j.min()), int(j.max()) + 1)
        matid = int(model.geom_matid[band[0]])
        rgba = model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[band[0]]
        columns = inside[window[0]:window[1], window[2]:window[3]]
        return cls(grid.lo, grid.h, window, columns, grid.shape[2], np.array([*rgba[:3], 1.0]), KERF_BAND)

    def snapshot(self, material: np.ndarray) -> np.ndarray:
        """The band's voxels of ``material`` (the grid's boolean array), packed to bits."""
        i0, i1, j0, j1 = self.window
        return np.packbits(material[i0:i1, j0:j1][self.columns])

    def unpack(self, packed: np.ndarray) -> np.ndarray:
        """The window's voxels (ni, nj, nz) from a snapshot; columns outside the band empty."""
        i0, i1, j0, j1 = self.window
        out = np.zeros((i1 - i0, j1 - j0, self.nz), bool)
        n = int(np.count_nonzero(self.columns)) * self.nz
        out[self.columns] = np.unpackbits(packed, count=n).astype(bool).reshape(-1, self.nz)
        return out

    def _z_runs(self, code: int) -> list[tuple[int, int]]:
        """[k0, k1) runs of the layers set in ``code`` (bit k: layer k has material)."""
        runs = self._runs.get(code)
        if runs is None:
            bits = [(code >> k) & 1 for k in range(self.nz)]
            edges = np.flatnonzero(np.diff(np.concatenate([[0], bits, [0]])))
            runs = [(int(a), int(b)) for a, b in edges.reshape(-1, 2)]
            self._runs[code] = runs
        return runs

    def boxes(self, packed: np.ndarray) -> np.ndarray:
        """(n, 6) boxes (centre, half size; world, m) covering the snapshot's voxels.

        Each column's layers as an integer code; runs of equal codes along y in each x row;
        a run continues the rectangle of the previous row with the same extent and code; each
        rectangle gives one box per run of layers."""
        codes = self.unpack(packed).astype(np.int64) @ self._layer_bits  # (ni, nj)
        rects: list[tuple[int, int, int, int, int]] = []  # i0, i1, j0, j1, code (window indices)
        open_: dict[tuple[int, int, int], int] = {}
        for i, row in enumerate(codes):
            edges = np.flatnonzero(np.diff(row)) + 1
            starts = np.concatenate([[0], edges])
            ends = np.concatenate([edges, [row.size]])
            now: dict[tuple[int, int, int], int] = {}
            for j0, j1 in zip(starts.tolist(), ends.tolist()):
                code = int(row[j0])
                if code == 0:
                    continue
                key = (j0, j1, code)
                k = open_.get(key)
                if k is None:
                    rects.append((i, i + 1, j0, j1, code))
                    k = len(rects) - 1
                else:
                    rects[k] = (rects[k][0], i + 1, j0, j1, code)
                now[key] = k
            open_ = now
        i_off, j_off = self.window[0], self.window[2]
        out = []
        for i0, i1, j0, j1, code in rects:
            for k0, k1 in self._z_runs(code):
                lo = self.lo + self.h * np.array([i0 + i_off, j0 + j_off, k0])
                hi = self.lo + self.h * np.array([i1 + i_off, j1 + j_off, k1])
                out.append(np.concatenate([(lo + hi) / 2, (hi - lo) / 2]))
        return np.array(out).reshape(-1, 6)

    def add_to_scene(self, scene: Any, boxes: np.ndarray) -> int:
        """Append ``boxes`` to the ``MjvScene`` as box geoms; returns how many fitted (maxgeom)."""
        import mujoco

        eye = np.eye(3).ravel()
        n = 0
        for box in boxes:
            if scene.ngeom >= scene.maxgeom:
                break
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_BOX, box[3:], box[:3], eye, self.rgba)
            scene.ngeom += 1
            n += 1
        return n


def project_points(model: Any, data: Any, camera: str, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixel (column, row) of world ``points`` in ``camera`` of a ``width``×``height`` image
    (MuJoCo's pinhole camera: ``fovy`` vertical, looking along −z; ``data`` after kinematics)."""
    cam = model.camera(camera).id
    local = (np.asarray(points, float) - data.cam_xpos[cam]) @ data.cam_xmat[cam].reshape(3, 3)  # x right, y up
    f = 0.5 * height / np.tan(np.radians(model.cam_fovy[cam]) / 2)
    return np.stack([width / 2 + f * local[:, 0] / -local[:, 2], height / 2 - f * local[:, 1] / -local[:, 2]], axis=1)


def kerf_region(model: Any, camera: str, polyline: np.ndarray, kerf_width: float, width: int, height: int) -> np.ndarray:
    """Mask (height, width) of the pixels of ``camera`` that show the planned kerf's top face.

    The kerf is ``polyline`` (its centre line at the plate's top, world, m) swept ``kerf_width``
    wide and half a width past its ends (the cutter's round ends), each leg a rectangle projected
    at the model's initial state (the close-up rides with the welded sample, which moves < 0.1 mm).
    To check a video: the cut is visible where these pixels change (tests/test_video_kerf.py,
    scripts/kerf_visibility.py).
    """
    import mujoco
    from matplotlib.path import Path

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    pixels = np.stack([cols.ravel(), rows.ravel()], axis=1)
    mask = np.zeros(width * height, bool)
    line, w = np.asarray(polyline, float), kerf_width / 2
    for a, b in zip(line[:-1], line[1:]):
        u = (b - a) / np.linalg.norm(b - a)
        n = np.array([-u[1], u[0], 0.0])
        a, b = a - w * u, b + w * u
        corners = np.array([a - w * n, b - w * n, b + w * n, a + w * n])
        mask |= Path(project_points(model, data, camera, corners, width, height)).contains_points(pixels)
    return mask.reshape(height, width)
