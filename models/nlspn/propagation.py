"""Non-local spatial propagation (NLSPN, Park et al., ECCV 2020), exportable to ONNX.

Each pixel ``p`` refines its depth from ``n = k*k - 1`` learned non-local neighbours. Neighbour ``j`` sits at
``p + t_j + o_j(p)``, where ``t_j`` is the ``j``-th off-centre position of a regular ``k x k`` grid (row-major,
``(dy, dx)``) and ``o_j`` a learned sub-pixel offset; it is read with bilinear interpolation, zero outside the
image. One step is

    d'(p) = a_c(p) d(p) + sum_j a_j(p) d(p + t_j + o_j(p)),    a_c = 1 - sum_j a_j,

i.e. a modulated deformable convolution (DCNv2) with an all-ones ``k x k`` kernel and the affinities as mask,
which is how the official code (zzangjinsun/NLSPN_ECCV20, ``src/model/nlspnmodel.py``) computes it. Offsets and
affinities are computed once and reused by every step.

Two interchangeable implementations (``impl``) give the same numbers:

- ``"grid_sample"`` (default): one ``F.grid_sample`` per step over all neighbours. Exports to ONNX
  ``GridSample`` (opset >= 16, every onnxruntime since 1.11); the fastest here on CPU.
- ``"deform_conv"``: ``torchvision.ops.deform_conv2d``, literally the official formulation. Exports to ONNX
  ``DeformConv`` (opset >= 19; needs onnxscript >= 0.7.1 to export and onnxruntime >= 1.25 to run).

Affinity normalisation (``affinity``), as upstream; ``a`` are the raw affinity logits:

- ``"TGASS"`` (Tanh-Gamma-Abs-Sum*, paper default): ``a = tanh(a) / gamma`` with a learnable ``gamma``
  initialised to ``affinity_gamma * n``, then divided by ``max(sum|a|, 1)``;
- ``"TC"`` (Tanh-Constant): ``a = tanh(a) / n``, no further normalisation;
- ``"AS"`` (Abs-Sum): ``a / sum|a|``;  ``"ASS"`` (Abs-Sum*): ``a / max(sum|a|, 1)``.

With ``conf_prop`` the affinities are multiplied by the confidence of each neighbour before normalisation
(``sum|a|`` gets ``+1e-4`` as upstream). So for TGASS/ASS ``sum_j |a_j| <= 1`` and the step is a convex-like
(stable) combination; for AS it equals 1 (up to the 1e-4).

Where the neighbour confidence is read (``confidence_sampling``) — upstream issue zzangjinsun/NLSPN_ECCV20#46:
upstream samples the confidence with a 1x1 deformable convolution whose offsets are the propagation offsets
``o_j`` *without* the kernel position ``t_j``, i.e. at ``p + o_j``, not at the neighbour ``p + t_j + o_j``. The
released ECCV checkpoints were trained with ``--legacy``, which adds ``t_j`` in place on a view of the offsets
and therefore also shifts the propagation to ``p + 2 t_j + o_j`` (a dilated kernel at initialisation).

- ``"offset"`` (default, upstream without ``--legacy``): confidence at ``p + o_j``.
- ``"neighbour"``: confidence at ``p + t_j + o_j``, the pixel whose depth the affinity weights — what the paper
  describes and what #46 asks for; propagation as upstream. An option to ablate, not upstream's training code.
- ``"legacy"``: upstream ``--legacy`` (confidence at ``p + t_j + o_j``, propagation at ``p + 2 t_j + o_j``), only
  for the released checkpoints.

As upstream, the offsets are detached where the confidence is sampled (no gradient through that path).

``preserve_input`` (default off, as upstream's ``--preserve_input`` flag) replaces the current estimate by the
sparse input at valid pixels (``sparse > 0``) *before every step* (upstream since commit abb87d8). The last step
therefore still mixes neighbours into the valid pixels: the output is not bit-equal to the input there. Turn it
on to anchor the propagation to the measurements (upstream's option, used with its released models).

Precision: the propagation always runs in float32, whatever the autocast context. Under ``16-mixed`` the
sampling positions ``p + t_j + o_j`` normalised to [-1, 1] would be half precision, i.e. quantised to 1/8-1/4
pixel at 512 pixels wide, and the 18 repeated steps would accumulate rounding; upstream trains in float32.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torchvision.ops import deform_conv2d

__all__ = [
    "AFFINITY_TYPES",
    "CONFIDENCE_SAMPLING",
    "PROPAGATION_IMPLS",
    "NonLocalPropagation",
    "PropagationOutput",
    "kernel_taps",
    "normalize_affinity",
    "sample_neighbours",
]

AFFINITY_TYPES = ("TGASS", "TC", "AS", "ASS")
CONFIDENCE_SAMPLING = ("neighbour", "offset", "legacy")
PROPAGATION_IMPLS = ("grid_sample", "deform_conv")


class PropagationOutput(NamedTuple):
    """Result of :class:`NonLocalPropagation`.

    Attributes:
        depth: refined depth ``[B, 1, H, W]`` after the last step (not clamped).
        offset: learned offsets ``o_j`` ``[B, n, 2, H, W]`` as ``(dy, dx)`` relative to the regular grid.
        affinity: normalised affinities ``[B, n + 1, H, W]`` in kernel order, centre ``a_c`` at index ``n // 2``
            (the upstream layout, i.e. the DCN mask).
    """

    depth: Tensor
    offset: Tensor
    affinity: Tensor


def kernel_taps(kernel_size: int = 3) -> Tensor:
    """The off-centre positions ``(dy, dx)`` of a ``k x k`` grid in row-major order, float ``[k*k - 1, 2]``.

    Example:
        >>> kernel_taps(3)[:4].tolist()
        [[-1.0, -1.0], [-1.0, 0.0], [-1.0, 1.0], [0.0, -1.0]]
    """
    if kernel_size < 3 or kernel_size % 2 != 1:
        raise ValueError(f"kernel_size must be an odd integer >= 3, got {kernel_size}")
    r = kernel_size // 2
    coords = torch.arange(-r, r + 1, dtype=torch.float32)
    grid = torch.stack(torch.meshgrid(coords, coords, indexing="ij"), dim=-1).reshape(-1, 2)
    centre = kernel_size * kernel_size // 2
    return torch.cat((grid[:centre], grid[centre + 1 :]))


def normalize_affinity(
    logits: Tensor, affinity: str, gamma: Tensor | float, confidence: Tensor | None = None
) -> tuple[Tensor, Tensor]:
    """Turn raw affinity logits into neighbour and centre affinities (upstream ``_get_offset_affinity``).

    Args:
        logits: raw affinities ``[B, n, H, W]``.
        affinity: one of :data:`AFFINITY_TYPES`.
        gamma: the scale ``gamma`` (TGASS learnable, TC ``n``; unused by AS/ASS).
        confidence: optional neighbour confidences ``[B, n, H, W]`` multiplied in before the normalisation.

    Returns:
        ``(neighbours [B, n, H, W], centre [B, 1, H, W])`` with ``centre = 1 - sum(neighbours)``.

    Example:
        >>> a, c = normalize_affinity(torch.randn(2, 8, 4, 4) * 10, "TGASS", 4.0)
        >>> bool((a.abs().sum(1) <= 1).all()), torch.allclose(c[:, 0] + a.sum(1), torch.ones(2, 4, 4))
        (True, True)
    """
    if affinity not in AFFINITY_TYPES:
        raise ValueError(f"affinity must be one of {AFFINITY_TYPES}, got {affinity!r}")
    aff = logits
    if affinity == "TC":
        aff = torch.tanh(aff) / gamma
    elif affinity == "TGASS":
        aff = torch.tanh(aff) / (gamma + 1e-8)
    if confidence is not None:
        aff = aff * confidence
    if affinity != "TC":
        abs_sum = aff.abs().sum(dim=1, keepdim=True) + 1e-4
        if affinity in ("ASS", "TGASS"):
            abs_sum = abs_sum.clamp(min=1.0)  # upstream: abs_sum[abs_sum < 1] = 1
        aff = aff / abs_sum
    return aff, 1.0 - aff.sum(dim=1, keepdim=True)


def sample_neighbours(x: Tensor, displacement: Tensor, impl: str = "grid_sample") -> Tensor:
    """Bilinearly sample a one-channel map at ``p + displacement_j(p)`` for every pixel ``p`` and neighbour ``j``.

    Pixel centres are at integer coordinates; reads outside the image are zero (DCNv2 / ``deform_conv2d``
    convention, equal to ``grid_sample(..., padding_mode="zeros", align_corners=True)``).

    Args:
        x: ``[B, 1, H, W]``.
        displacement: ``[B, n, 2, H, W]`` as ``(dy, dx)`` in pixels.
        impl: one of :data:`PROPAGATION_IMPLS`. ``"deform_conv"`` needs ``n = k*k - 1`` (the off-centre taps).

    Returns:
        ``[B, n, H, W]``.

    Example:
        >>> x = torch.arange(12.0).view(1, 1, 3, 4)
        >>> d = torch.tensor([0.0, 1.0]).view(1, 1, 2, 1, 1).expand(1, 1, 2, 3, 4)  # one pixel to the right
        >>> sample_neighbours(x, d)[0, 0].tolist()
        [[1.0, 2.0, 3.0, 0.0], [5.0, 6.0, 7.0, 0.0], [9.0, 10.0, 11.0, 0.0]]
    """
    b, n, _, h, w = displacement.shape
    if impl == "grid_sample":
        grid = _sampling_grid(displacement)
        return F.grid_sample(x, grid, mode="bilinear", padding_mode="zeros", align_corners=True).view(
            b, n, h, w
        )
    if impl == "deform_conv":
        kernel_size = round((n + 1) ** 0.5)
        if kernel_size * kernel_size != n + 1:
            raise ValueError(f"deform_conv sampling needs n = k*k - 1 neighbours, got n={n}")
        taps = kernel_taps(kernel_size).to(displacement)
        # One output channel per neighbour, each reading only its own kernel tap (the centre tap is skipped).
        tap_index = [j if j < n // 2 else j + 1 for j in range(n)]
        eye = torch.eye(kernel_size * kernel_size, dtype=x.dtype, device=x.device)
        weight = eye[tap_index].view(n, 1, kernel_size, kernel_size)
        offset = _dcn_offset(displacement - taps.view(1, n, 2, 1, 1))
        return deform_conv2d(x, offset, weight, padding=kernel_size // 2)
    raise ValueError(f"impl must be one of {PROPAGATION_IMPLS}, got {impl!r}")


class NonLocalPropagation(nn.Module):
    """NLSPN propagation layer: learned offsets and affinities from guidance, then ``steps`` refinement steps.

    Parameter names match upstream's ``NLSPN`` module (``conv_offset_aff``, ``aff_scale_const``). The
    offset/affinity convolution is zero-initialised as upstream: all neighbour affinities start at 0 (centre 1),
    so propagation starts as the identity and learns its affinities (then offsets) from there.

    Args:
        guidance_channels: channels of the guidance map (default ``k*k - 1``, as upstream).
        kernel_size: ``k`` of the ``k x k`` neighbourhood; ``n = k*k - 1`` neighbours (3 -> 8, the paper's).
        steps: number of propagation steps (paper: 18).
        affinity: normalisation, one of :data:`AFFINITY_TYPES` (paper: ``"TGASS"``).
        affinity_gamma: TGASS initial ``gamma / n`` (upstream default 0.5).
        conf_prop: weight affinities by the neighbours' confidence (needs ``confidence`` in ``forward``).
        preserve_input: reset valid sparse pixels before every step (needs ``sparse_depth`` in ``forward``);
            off by default, as upstream.
        confidence_sampling: where neighbour confidences are read, one of :data:`CONFIDENCE_SAMPLING`;
            ``"offset"`` (upstream) by default (see the module docstring and upstream issue #46).
        impl: propagation implementation, one of :data:`PROPAGATION_IMPLS`.

    Example:
        >>> prop = NonLocalPropagation(steps=3)
        >>> out = prop(torch.rand(2, 1, 16, 16), torch.randn(2, 8, 16, 16), confidence=torch.rand(2, 1, 16, 16),
        ...            sparse_depth=torch.zeros(2, 1, 16, 16))
        >>> out.depth.shape, out.offset.shape, out.affinity.shape
        (torch.Size([2, 1, 16, 16]), torch.Size([2, 8, 2, 16, 16]), torch.Size([2, 9, 16, 16]))
    """

    aff_scale_const: Tensor
    taps: Tensor

    def __init__(
        self,
        guidance_channels: int | None = None,
        kernel_size: int = 3,
        steps: int = 18,
        affinity: str = "TGASS",
        affinity_gamma: float = 0.5,
        conf_prop: bool = True,
        preserve_input: bool = False,
        confidence_sampling: str = "offset",
        impl: str = "grid_sample",
    ) -> None:
        super().__init__()
        taps = kernel_taps(kernel_size)
        n = taps.shape[0]
        if affinity not in AFFINITY_TYPES:
            raise ValueError(f"affinity must be one of {AFFINITY_TYPES}, got {affinity!r}")
        if confidence_sampling not in CONFIDENCE_SAMPLING:
            raise ValueError(
                f"confidence_sampling must be one of {CONFIDENCE_SAMPLING}, got {confidence_sampling!r}"
            )
        if impl not in PROPAGATION_IMPLS:
            raise ValueError(f"impl must be one of {PROPAGATION_IMPLS}, got {impl!r}")
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps}")
        if affinity == "TGASS" and affinity_gamma <= 0:
            raise ValueError(f"affinity_gamma must be > 0, got {affinity_gamma}")

        self.kernel_size = kernel_size
        self.num_neighbours = n
        self.steps = steps
        self.affinity = affinity
        self.conf_prop = conf_prop
        self.preserve_input = preserve_input
        self.confidence_sampling = confidence_sampling
        self.impl = impl

        guidance_channels = n if guidance_channels is None else guidance_channels
        # Output channels: dy/dx offsets (2n, pairs per neighbour as upstream's view(B, n, 2, H, W)) + n affinities.
        self.conv_offset_aff = nn.Conv2d(guidance_channels, 3 * n, kernel_size=3, padding=1)
        nn.init.zeros_(self.conv_offset_aff.weight)
        nn.init.zeros_(self.conv_offset_aff.bias)
        if affinity == "TGASS":
            self.aff_scale_const = nn.Parameter(torch.full((1,), affinity_gamma * n))
        else:  # fixed: n for TC, unused (1) for AS/ASS; a buffer so optimisers never see it
            self.register_buffer("aff_scale_const", torch.full((1,), float(n) if affinity == "TC" else 1.0))
        self.register_buffer("taps", taps, persistent=False)

    def extra_repr(self) -> str:
        return (
            f"kernel_size={self.kernel_size}, steps={self.steps}, affinity={self.affinity!r}, "
            f"conf_prop={self.conf_prop}, preserve_input={self.preserve_input}, "
            f"confidence_sampling={self.confidence_sampling!r}, impl={self.impl!r}"
        )

    def forward(
        self,
        init_depth: Tensor,
        guidance: Tensor,
        confidence: Tensor | None = None,
        sparse_depth: Tensor | None = None,
    ) -> PropagationOutput:
        """Refine ``init_depth`` ``[B, 1, H, W]`` guided by ``guidance`` ``[B, C_g, H, W]``, in float32.

        Args:
            init_depth: initial dense depth.
            guidance: guidance features (affinity/offset logits come from a 3x3 conv on them).
            confidence: ``[B, 1, H, W]`` in [0, 1]; required when ``conf_prop``.
            sparse_depth: ``[B, 1, H, W]``, 0 = no measurement; required when ``preserve_input``.

        Returns:
            float32 outputs, also under autocast (see the module docstring).
        """
        self._check_inputs(init_depth, guidance, confidence, sparse_depth)
        device = guidance.device.type
        if torch.is_autocast_enabled(device):
            # Only entered under autocast, so exported graphs (traced without it) carry no autocast node.
            with torch.autocast(device, enabled=False):
                return self._propagate(*(_fp32(t) for t in (init_depth, guidance, confidence, sparse_depth)))
        return self._propagate(*(_fp32(t) for t in (init_depth, guidance, confidence, sparse_depth)))

    def _propagate(
        self,
        init_depth: Tensor,
        guidance: Tensor,
        confidence: Tensor | None,
        sparse_depth: Tensor | None,
    ) -> PropagationOutput:
        b, _, h, w = guidance.shape
        n = self.num_neighbours
        taps = self.taps.to(guidance.dtype).view(1, n, 2, 1, 1)

        offset_logits, aff_logits = self.conv_offset_aff(guidance).split((2 * n, n), dim=1)
        offset = offset_logits.reshape(b, n, 2, h, w)
        legacy = self.confidence_sampling == "legacy"
        displacement = taps + offset + taps if legacy else taps + offset

        neighbour_conf = None
        if self.conf_prop:
            assert confidence is not None  # checked above
            if self.confidence_sampling == "offset":
                conf_displacement = offset.detach()
            else:  # "neighbour" and "legacy" read it at p + t_j + o_j
                conf_displacement = (taps + offset).detach()
            neighbour_conf = sample_neighbours(confidence, conf_displacement, self.impl)
        aff, aff_centre = normalize_affinity(aff_logits, self.affinity, self.aff_scale_const, neighbour_conf)

        mask = sparse_depth > 0 if self.preserve_input else None
        depth = init_depth
        if self.impl == "grid_sample":
            grid = _sampling_grid(displacement)  # built once, reused by every step
            for _ in range(self.steps):
                if mask is not None:
                    depth = torch.where(mask, sparse_depth, depth)
                neighbours = F.grid_sample(
                    depth, grid, mode="bilinear", padding_mode="zeros", align_corners=True
                )
                depth = aff_centre * depth + (aff * neighbours.view(b, n, h, w)).sum(dim=1, keepdim=True)
        else:
            dcn_offset = _dcn_offset(displacement - taps)
            dcn_mask = _insert_centre(aff, aff_centre)
            ones = torch.ones(
                1, 1, self.kernel_size, self.kernel_size, dtype=depth.dtype, device=depth.device
            )
            for _ in range(self.steps):
                if mask is not None:
                    depth = torch.where(mask, sparse_depth, depth)
                depth = deform_conv2d(depth, dcn_offset, ones, padding=self.kernel_size // 2, mask=dcn_mask)
        return PropagationOutput(depth, offset, _insert_centre(aff, aff_centre))

    def _check_inputs(
        self, init_depth: Tensor, guidance: Tensor, confidence: Tensor | None, sparse_depth: Tensor | None
    ) -> None:
        if guidance.ndim != 4 or guidance.shape[1] != self.conv_offset_aff.in_channels:
            raise ValueError(
                f"guidance must be [B, {self.conv_offset_aff.in_channels}, H, W], got {tuple(guidance.shape)}"
            )
        b, _, h, w = guidance.shape
        if h < 2 or w < 2:
            raise ValueError(f"guidance must be at least 2x2 pixels, got {h}x{w}")
        expected = (b, 1, h, w)
        named = {"init_depth": init_depth}
        if self.conf_prop:
            if confidence is None:
                raise ValueError("confidence is required when conf_prop=True")
            named["confidence"] = confidence
        if self.preserve_input:
            if sparse_depth is None:
                raise ValueError("sparse_depth is required when preserve_input=True")
            named["sparse_depth"] = sparse_depth
        for name, t in named.items():
            if tuple(t.shape) != expected:
                raise ValueError(f"{name} must have shape {expected} (like guidance), got {tuple(t.shape)}")


def _fp32(t: Tensor | None) -> Tensor | None:
    """Half-precision ``t`` as float32; anything else unchanged (float32 input leaves exported graphs as they
    were, and a model converted to float64 stays float64)."""
    return t.float() if t is not None and t.dtype in (torch.float16, torch.bfloat16) else t


def _sampling_grid(displacement: Tensor) -> Tensor:
    """``grid_sample`` grid ``[B, n*H, W, 2]`` for positions ``p + displacement`` (align_corners=True)."""
    b, n, _, h, w = displacement.shape
    ys = torch.arange(h, dtype=displacement.dtype, device=displacement.device).view(1, 1, h, 1)
    xs = torch.arange(w, dtype=displacement.dtype, device=displacement.device).view(1, 1, 1, w)
    gx = (xs + displacement[:, :, 1]) * (2.0 / (w - 1)) - 1.0
    gy = (ys + displacement[:, :, 0]) * (2.0 / (h - 1)) - 1.0
    # Neighbours stacked along the height axis: one grid_sample call reads all of them.
    return torch.stack((gx, gy), dim=-1).view(b, n * h, w, 2)


def _insert_centre(neighbours: Tensor, centre: Tensor) -> Tensor:
    """``[B, n, ...]`` + ``[B, 1, ...]`` -> ``[B, n + 1, ...]`` with the centre at kernel index ``n // 2``."""
    half = neighbours.shape[1] // 2
    return torch.cat((neighbours[:, :half], centre, neighbours[:, half:]), dim=1)


def _dcn_offset(tap_offset: Tensor) -> Tensor:
    """Neighbour offsets ``[B, n, 2, H, W]`` -> DCN offsets ``[B, 2(n + 1), H, W]`` with a zero centre tap."""
    b, n, _, h, w = tap_offset.shape
    centre = tap_offset.new_zeros(b, 1, 2, h, w)
    return _insert_centre(tap_offset, centre).reshape(b, 2 * (n + 1), h, w)
