"""The remap part of a served sample: the lookup tables from cube faces or panoramas to the sample's camera (the
split's lens, a lens drawn per sample, a gimbal view), built once and kept in a bounded cache, and each sample's
draw of view and lens. A mixin of :class:`~datamodules.dataset.AirFisheyeDataset`, which sets what it reads:
``reader``, ``spec``, ``split``, ``source``, ``camera``, ``served_lenses``, ``lens_draws``, ``gimbal``, ``seed``,
``face_size`` and its table cache (docs/design.md, "Serving a sample", "Virtual gimbal", "Lenses drawn per sample").
"""

from __future__ import annotations

import logging
from functools import cached_property

import torch

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.geometry import CubemapToFisheye, EquirectToFisheye
from airfisheye_bench.geometry.cameras import CameraModel
from airfisheye_bench.geometry.gimbal import Gimbal, View
from airfisheye_bench.geometry.lens_draws import LensDraw
from airfisheye_bench.geometry.ray_maps import ray_map
from airfisheye_bench.geometry.remap_table import TableCache, reserve_tables
from datamodules.device_remap import DeviceRemap
from datamodules.sampling import draw_seed

log = logging.getLogger(__name__)

#: Memory the lookup tables of a split's views and lenses may take per process; those beyond it are rebuilt in turn.
GIMBAL_TABLE_BUDGET_BYTES = 1 << 30


class RemapServing:
    """The remap tables of a split and each sample's view and lens."""

    @cached_property
    def valid_mask(self) -> torch.Tensor:
        """``[H, W]`` pixels that carry data (inside the image circle, on a cube face, on the calibrated sensor), at
        the split's one orientation (a sample of a varying gimbal serves its own view's in ``valid_mask``)."""
        return self._valid(self._remap, self._outside_frame)

    @cached_property
    def ray_map(self) -> torch.Tensor:
        """``[4, H, W]`` the ray map of the split's camera over its pixels with data (:attr:`valid_mask`): the
        ``rays`` of every sample of a fixed lens, one tensor for all (docs/design.md, "Ray map")."""
        return ray_map(self.camera, self.valid_mask)

    def sample_rays(
        self, remap: CubemapToFisheye | EquirectToFisheye | None, valid: torch.Tensor
    ) -> torch.Tensor:
        """A sample's ``rays``: the ray map of its remap's camera (its lens) over ``valid``, its pixels with data
        before the augmentation. The split's lens gives :attr:`ray_map`; a lens drawn per sample (or a gimbal view)
        gives its cached remap's, whose camera's rays are cached with it. The augmentation leaves the map as it is:
        its flips and rotations turn the image about the principal point, which keeps every pixel's ray of a lens
        symmetric about its axis."""
        if remap is self._remap:
            return self.ray_map
        return ray_map(remap.camera, valid)

    def _valid(
        self, remap: CubemapToFisheye | EquirectToFisheye | None, outside: torch.Tensor | None
    ) -> torch.Tensor:
        valid = remap.valid_mask if remap is not None else self.camera.valid_mask()
        return valid & ~outside if outside is not None else valid

    def _table_cache(self) -> TableCache:
        """The cache of the remaps of the views and lenses beyond the split's first: as many as the budget holds."""
        cache = TableCache(maxsize=1)
        if self._remap is not None and self._remap_count() > 1:
            kept = min(self._remap_count(), max(1, GIMBAL_TABLE_BUDGET_BYTES // self._remap_bytes()))
            cache.maxsize = kept + 1
            reserve_tables(2 * kept + 2)  # bilinear and nearest
        return cache

    def warm_up(self) -> None:
        """Build the remap lookup tables now, so DataLoader workers inherit them instead of rebuilding them.

        With a virtual gimbal or lenses drawn per sample, every view's and lens's tables when they fit
        :data:`GIMBAL_TABLE_BUDGET_BYTES` (the rest are built when first served, in the process that serves them,
        and kept in a cache of that size).
        """
        if self._remap is None:
            return
        keys: list[tuple[View, LensDraw | None]] = [(self._base_view, None)]
        count = self._remap_count()
        if count > 1:
            fits = self._remaps.maxsize - 1  # sized by the budget (__init__)
            if count <= fits:
                varying_view = self.gimbal is not None and self.gimbal.fixed is None
                views = self.gimbal.all_views() if varying_view else [self._base_view]
                lenses = range(len(self.served_lenses))
                draws = [LensDraw(i) for i in lenses] if self._lenses_vary else [None]
                keys = [(view, draw) for view in views for draw in draws]
                log.info("building the lookup tables of %d views and lenses (%s)", len(keys), self.split)
            else:
                log.warning(
                    "data.gimbal / data.camera: %d views and lenses, the tables of %d fit in %d MB; the others are "
                    "built when served (tens of ms each at this size): a coarser data.gimbal.step_deg or a smaller "
                    "data.camera.jitter keeps them all",
                    count,
                    fits,
                    GIMBAL_TABLE_BUDGET_BYTES >> 20,
                )
        for view, draw in keys:
            remap = self._remap_for(view, draw)
            for mode in ("bilinear", "nearest"):
                remap.table(mode)

    @property
    def _lenses_vary(self) -> bool:
        return self.lens_draws is not None and self.lens_draws.varies

    def _remap_count(self) -> int:
        """How many remaps (a view and a lens each) this split can serve."""
        views = self.gimbal.view_count() if self.gimbal is not None else 1
        if not self._lenses_vary:
            return views
        pool = self.lens_draws.pool
        return views * (self.lens_draws.count() if pool is None else min(pool, self.lens_draws.count()))

    def _remap_bytes(self) -> int:
        """About what one view's or lens's remap holds: its two tables (bilinear taps and weights, nearest index,
        two pixel lists) over the valid pixels, and its camera's per-pixel grids (rays, validity, scale)."""
        pixels = self.camera.width * self.camera.height
        return int(self.camera.valid_mask().sum()) * (4 * 8 + 8 + 2 * 8) + pixels * (3 * 8 + 3 * 4 + 8 + 1)

    def _remap_for(self, view: View, draw: LensDraw | None = None) -> CubemapToFisheye | EquirectToFisheye:
        """The remap of the camera turned to ``view`` through lens ``draw`` (``None``: the first, unjittered): one
        object per view and lens, the latest kept (:meth:`warm_up` sizes the cache); the tables live in the process
        cache."""
        key = (tuple(view), draw)
        if key == (self._base_view, None) and self._remap is not None:
            return self._remap
        return self._remaps.get(key, lambda: self._build_remap(view, draw))

    def _build_remap(self, view: View, draw: LensDraw | None) -> CubemapToFisheye | EquirectToFisheye:
        """A panorama's camera is its source's recorded one, ``R_pano_cam0`` (``pano_rotation``), turned by the
        view."""
        camera = self._camera_of(draw)
        turn = Gimbal.rotation(view)
        if self.source == "cubemap":
            return CubemapToFisheye(camera, self.face_size, rotation=turn)
        recorded = self.reader.pano_rotation
        rotation = recorded if turn is None else turn if recorded is None else recorded @ turn
        return EquirectToFisheye(camera, self.spec.equirect_size, rotation=rotation)

    def _camera_of(self, draw: LensDraw | None) -> CameraModel:
        """The camera of a lens draw: its lens of the list, perturbed by its jitter."""
        if draw is None:
            return self.camera
        return draw.jitter.apply(self.served_lenses[draw.lens].camera)

    def lens_camera(self, lens: int, lens_params: torch.Tensor) -> CameraModel:
        """The camera a sample was served through, from its ``lens`` and ``lens_params`` (a ray map:
        ``lens_camera(...).ray_grid()``)."""
        count = len(self.served_lenses[int(lens)].camera.distortion_params)
        return self._camera_of(LensDraw.from_params(int(lens), lens_params, count))

    def sample_lens(self, index: int) -> LensDraw | None:
        """The lens of sample ``index`` in the current epoch (``None``: the one lens of ``data.camera``)."""
        if self.lens_draws is None:
            return None
        if not self.lens_draws.training:
            return self.lens_draws.draw(index, None)
        epoch = self._epoch.get()
        seed = draw_seed(self.seed, epoch, index)
        if (
            self.lens_draws.pool is not None
        ):  # one of the epoch's lenses: the slot's own draw, whoever serves it
            slot = seed % self.lens_draws.pool
            seed = draw_seed(self.seed, epoch, -1 - slot)
        return self.lens_draws.draw(index, seed)

    def sample_view(self, index: int) -> View | None:
        """The gimbal view of sample ``index`` in the current epoch (``None`` without a gimbal)."""
        if self.gimbal is None:
            return None
        draw = draw_seed(self.seed, self._epoch.get(), index) if self.gimbal.training else None
        return self.gimbal.view(index, draw)

    def device_remap(self) -> DeviceRemap:
        """The device half of ``data.remap_on=device`` for this dataset's camera and faces."""
        if self.source != "cubemap" or self._depth_from_points:
            raise ConfigError(
                f"data.remap_on=device: data.source={self.source} (data.format={self.reader.format}): the device "
                "remaps cube faces only; use data.remap_on=worker"
            )
        if self.gimbal is not None and self.gimbal.fixed is None:
            raise ConfigError(
                f"data.remap_on=device: data.gimbal serves the {self.split!r} split through a view per sample, each "
                "with its own lookup table, and a batch is remapped with one; use data.remap_on=worker, or one "
                "fixed view (data.gimbal=[yaw,pitch])"
            )
        if self.lens_draws is not None and self.lens_draws.varies:
            raise ConfigError(
                f"data.remap_on=device: data.camera.lenses / jitter serve the {self.split!r} split through a lens per "
                "sample, each with its own lookup table, and a batch is remapped with one; use data.remap_on=worker"
            )
        return DeviceRemap(
            self._remap,
            self.valid_mask,
            self._outside_frame,
            self.label_lut,
            self.spec.ignore_index,
            self.max_depth,
        )
