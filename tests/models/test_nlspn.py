"""NLSPN: the shared model tests, the propagation against plain references, and the completion loss."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pytest
import torch
import torchvision
from torch import Tensor, nn

import models
from airfisheye_bench.export import export_onnx, verify_onnx
from models.losses.completion import L1L2Loss, NLSPNLoss, masked_l1_l2
from models.nlspn import NLSPN, NonLocalPropagation, kernel_taps, normalize_affinity, sample_neighbours
from tests.helpers.model_tester import BaseModelTester

TAPS_3X3 = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]  # kernel order; index 4 is the centre


def perturb_propagation(
    prop: NonLocalPropagation, seed: int = 0, offset_std: float = 1.0, signed_affinity: bool = False
) -> None:
    """Replace upstream's zero initialisation (identity propagation) by random offsets and affinities, so that
    tests exercise non-trivial sampling: offsets of a few pixels (some neighbours fall outside small images).

    By default the affinities are positive, as in a trained model: then every step is a convex combination and
    18 steps stay bounded. ``signed_affinity`` also gives negative ones (centre affinity up to 2), whose repeated
    application can amplify values (and float32 rounding) exponentially; fine for a few steps on small maps.
    """
    g = torch.Generator().manual_seed(seed)
    n = prop.num_neighbours
    with torch.no_grad():
        weight = prop.conv_offset_aff.weight
        weight.copy_(0.3 * torch.randn(weight.shape, generator=g) / math.sqrt(weight[0].numel()))
        bias = prop.conv_offset_aff.bias
        bias[: 2 * n].copy_(offset_std * torch.randn(2 * n, generator=g))
        if signed_affinity:
            bias[2 * n :].copy_(torch.randn(n, generator=g))
        else:
            weight[2 * n :] *= 0.2
            bias[2 * n :].copy_(0.5 + 1.5 * torch.rand(n, generator=g))


class TestNLSPN(BaseModelTester):
    model_name = "nlspn"
    task = "completion"
    model_kwargs: ClassVar[dict] = {"encoder_name": "resnet18", "prop_steps": 3}
    input_sizes = ((32, 48), (34, 26), (48, 32))  # any size works (decoder maps are cropped to the skips)
    output_stride = 1
    aux_keys = ("initial_depth", "confidence", "guidance", "offset", "affinity")
    # The defaults are the paper's configuration: ResNet34, 18 steps, TGASS, 8 neighbours.
    paper_kwargs: ClassVar[dict | None] = {}

    # Upstream's zero-initialised propagation is the identity; perturb it so every shared test (ONNX parity,
    # gradients, ...) also exercises the learned offsets and affinities.
    def make_model(self, seed: int = 0, **overrides) -> nn.Module:
        model = super().make_model(seed, **overrides)
        perturb_propagation(model.prop_layer, seed)
        return model

    def _paper_model(self) -> nn.Module:
        model = super()._paper_model()
        perturb_propagation(model.prop_layer)
        return model

    def test_too_small_input_raises(self):
        model = self.make_model().eval()
        with pytest.raises(ValueError, match="16"):
            model(**self.make_inputs(1, (15, 64)))

    def test_aux_outputs_with_learned_offsets(self):
        model = self.make_model().eval()
        inputs = self.make_inputs(2, (32, 48))
        with torch.no_grad():
            out = model.forward_with_aux(**inputs)
        assert out["offset"].abs().max() > 0.5  # the perturbed propagation is not the identity
        assert out["affinity"].shape == (2, 9, 32, 48)
        assert ((out["confidence"] >= 0) & (out["confidence"] <= 1)).all()


class TestNLSPNRays(TestNLSPN):
    """The ray map at the RGB stem and at the first layer of each full-resolution head."""

    model_kwargs: ClassVar[dict] = {**TestNLSPN.model_kwargs, "camera_input": "rays"}
    paper_kwargs = None


def test_paper_architecture_matches_upstream_layer_by_layer():
    """Parameter count derived from upstream's layer list (nlspnmodel.py) and torchvision's ResNet34 stages."""

    def conv(cin: int, cout: int, bias: bool) -> int:
        return cin * cout * 9 + (cout if bias else 0)

    def conv_bn(cin: int, cout: int) -> int:
        return conv(cin, cout, bias=False) + 2 * cout

    resnet = torchvision.models.resnet34(weights=None)
    stages = sum(p.numel() for name, p in resnet.named_parameters() if name.startswith("layer"))
    expected = (
        stages
        + conv(3, 48, True) + conv(1, 16, True) + conv_bn(512, 512)  # stems, conv6
        + conv_bn(512, 256) + conv_bn(768, 128) + conv_bn(384, 64) + conv_bn(192, 64)  # dec5..dec2
        + conv_bn(128, 64) + conv(128, 1, True)  # initial depth head
        + conv_bn(128, 64) + conv(128, 8, True)  # guidance head
        + conv_bn(128, 32) + conv(96, 1, True)  # confidence head
        + conv(8, 24, True) + 1  # offset/affinity conv and the learnable TGASS gamma
    )  # fmt: skip
    model = models.create_model("nlspn")
    assert sum(p.numel() for p in model.parameters()) == expected
    keys = set(model.state_dict())  # upstream names, so its checkpoints map one to one
    for key in ("conv1_rgb.0.weight", "conv2.2.conv2.weight", "conv6.1.running_var", "dec2.0.weight",
                "id_dec0.0.bias", "gd_dec0.0.weight", "cf_dec0.0.weight", "prop_layer.conv_offset_aff.weight",
                "prop_layer.aff_scale_const"):  # fmt: skip
        assert key in keys, key
    prop = model.prop_layer
    assert (prop.steps, prop.num_neighbours, prop.affinity) == (18, 8, "TGASS")
    assert isinstance(prop.aff_scale_const, nn.Parameter) and prop.aff_scale_const.item() == 0.5 * 8
    assert not prop.conv_offset_aff.weight.any() and not prop.conv_offset_aff.bias.any()  # zero init


def test_encoder_weights_file_loads_torchvision_stages(tmp_path):
    resnet = torchvision.models.resnet18(weights=None)
    torch.save(resnet.state_dict(), tmp_path / "resnet18.pth")
    model = NLSPN(encoder_name="resnet18", encoder_weights=tmp_path / "resnet18.pth")
    assert torch.equal(model.conv2[0].conv1.weight, resnet.layer1[0].conv1.weight)
    assert torch.equal(model.conv5[1].bn2.running_var, resnet.layer4[1].bn2.running_var)
    assert model.weights_identity["encoder_weights"]["file"] == str((tmp_path / "resnet18.pth").resolve())
    with pytest.raises(ValueError, match="resnet34"):  # resnet18 weights lack resnet34's extra blocks
        NLSPN(encoder_name="resnet34", encoder_weights=tmp_path / "resnet18.pth")
    with pytest.raises(ValueError, match="does not exist"):
        NLSPN(encoder_name="resnet18", encoder_weights=tmp_path / "missing.pth")
    with pytest.raises(ValueError, match="encoder"):
        NLSPN(encoder_name="resnet50")


def test_weights_path_round_trip(tmp_path):
    source = models.create_model("nlspn", encoder_name="resnet18", affinity="TC")
    perturb_propagation(source.prop_layer)
    torch.save({"state_dict": {f"model.{k}": v for k, v in source.state_dict().items()}}, tmp_path / "w.ckpt")
    loaded = models.create_model(
        "nlspn", encoder_name="resnet18", affinity="TC", weights_path=tmp_path / "w.ckpt"
    )
    for (name, a), b in zip(source.state_dict().items(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b), name


# ---------------------------------------------------------------------------------------------------------------
# Propagation against a plain reference


def bilinear(img: np.ndarray, y: float, x: float) -> float:
    """Bilinear read at (y, x), pixel centres at integers, zero outside the image (DCNv2 convention)."""
    h, w = img.shape
    y0, x0 = math.floor(y), math.floor(x)
    value = 0.0
    for yy, wy in ((y0, 1.0 - (y - y0)), (y0 + 1, y - y0)):
        for xx, wx in ((x0, 1.0 - (x - x0)), (x0 + 1, x - x0)):
            if 0 <= yy < h and 0 <= xx < w:
                value += wy * wx * img[yy, xx]
    return value


def reference_propagation(
    prop: NonLocalPropagation, init: Tensor, guidance: Tensor, conf: Tensor, sparse: Tensor
) -> tuple[np.ndarray, dict[str, int]]:
    """NLSPN propagation written out per pixel in float64: explicit bilinear reads of the 9 kernel taps.

    Returns the depth and counts of the cases visited (to check the test covers borders and both branches of
    the Abs-Sum* normalisation).
    """
    with torch.no_grad():
        raw = prop.conv_offset_aff(guidance).double().numpy()
    gamma = prop.aff_scale_const.item()
    init, conf, sparse = (t.double().numpy()[:, 0] for t in (init, conf, sparse))
    b_size, h, w = init.shape
    n = 8
    cases = {"outside": 0, "partly_outside": 0, "sum_below_1": 0, "sum_above_1": 0}
    out = np.zeros_like(init)
    for b in range(b_size):
        positions = np.zeros((h, w, 9, 2))  # sampling position of each tap, centre included
        weights = np.zeros((h, w, 9))
        for y in range(h):
            for x in range(w):
                aff = []
                for j in range(n):
                    tap = TAPS_3X3[j if j < 4 else j + 1]
                    # Upstream layout: channels [o1; o2] viewed as (n, 2): neighbour j's (dy, dx) = 2j, 2j + 1.
                    oy, ox = raw[b, 2 * j, y, x], raw[b, 2 * j + 1, y, x]
                    a = raw[b, 2 * n + j, y, x]
                    if prop.affinity == "TGASS":
                        a = math.tanh(a) / (gamma + 1e-8)
                    elif prop.affinity == "TC":
                        a = math.tanh(a) / gamma
                    if prop.confidence_sampling == "offset":
                        conf_at = (y + oy, x + ox)
                    else:
                        conf_at = (y + tap[0] + oy, x + tap[1] + ox)
                    if prop.conf_prop:
                        a *= bilinear(conf[b], *conf_at)
                    shift = 2 if prop.confidence_sampling == "legacy" else 1
                    pos = (y + shift * tap[0] + oy, x + shift * tap[1] + ox)
                    positions[y, x, j if j < 4 else j + 1] = pos
                    if not (-1 < pos[0] < h and -1 < pos[1] < w):
                        cases["outside"] += 1
                    elif not (0 <= pos[0] <= h - 1 and 0 <= pos[1] <= w - 1):
                        cases["partly_outside"] += 1
                    aff.append(a)
                if prop.affinity != "TC":
                    s = sum(abs(a) for a in aff) + 1e-4
                    cases["sum_below_1" if s < 1 else "sum_above_1"] += 1
                    if prop.affinity in ("ASS", "TGASS"):
                        s = max(s, 1.0)
                    aff = [a / s for a in aff]
                weights[y, x] = [*aff[:4], 1.0 - sum(aff), *aff[4:]]
                positions[y, x, 4] = (y, x)
        depth = init[b].copy()
        for _ in range(prop.steps):
            if prop.preserve_input:
                depth = np.where(sparse[b] > 0, sparse[b], depth)
            new = np.zeros_like(depth)
            for y in range(h):
                for x in range(w):
                    new[y, x] = sum(weights[y, x, k] * bilinear(depth, *positions[y, x, k]) for k in range(9))
            depth = new
        out[b] = depth
    return out, cases


def propagation_inputs(b: int = 2, h: int = 7, w: int = 9, seed: int = 0) -> dict[str, Tensor]:
    g = torch.Generator().manual_seed(seed)
    sparse = (1 + 9 * torch.rand(b, 1, h, w, generator=g)) * (torch.rand(b, 1, h, w, generator=g) < 0.2)
    return {
        "init_depth": 10 * torch.rand(b, 1, h, w, generator=g),
        "guidance": torch.randn(b, 8, h, w, generator=g),
        "confidence": torch.rand(b, 1, h, w, generator=g),
        "sparse_depth": sparse,
    }


@pytest.mark.parametrize("impl", ["grid_sample", "deform_conv"])
@pytest.mark.parametrize(
    ("affinity", "confidence_sampling", "conf_prop", "preserve_input"),
    [
        ("TGASS", "neighbour", True, True),
        ("TGASS", "offset", True, True),
        ("TGASS", "legacy", True, True),
        ("TGASS", "neighbour", False, False),
        ("TC", "neighbour", True, True),
        ("AS", "neighbour", True, False),
        ("ASS", "offset", True, True),
    ],
)
def test_propagation_matches_plain_reference(impl, affinity, confidence_sampling, conf_prop, preserve_input):
    prop = NonLocalPropagation(
        steps=3, affinity=affinity, confidence_sampling=confidence_sampling, conf_prop=conf_prop,
        preserve_input=preserve_input, impl=impl,
    )  # fmt: skip
    perturb_propagation(prop, offset_std=2.0, signed_affinity=True)
    if affinity == "TGASS":
        prop.aff_scale_const.data.fill_(1.5)  # any learned gamma > 0; small enough for sum|a| > 1 to occur
    inputs = propagation_inputs()
    with torch.no_grad():
        out = prop(**inputs)
    expected, cases = reference_propagation(prop, *inputs.values())
    # The random offsets reach outside the 7x9 image, fully and partly, and TGASS/ASS hit both branches.
    assert cases["outside"] > 0 and cases["partly_outside"] > 0
    if affinity in ("TGASS", "ASS") and conf_prop:
        assert cases["sum_below_1"] > 0 and cases["sum_above_1"] > 0
    np.testing.assert_allclose(out.depth[:, 0].double().numpy(), expected, rtol=1e-4, atol=1e-4)


def upstream_propagation(prop: NonLocalPropagation, inputs: dict[str, Tensor], legacy: bool) -> Tensor:
    """Upstream's TGASS propagation step by step (``NLSPN._get_offset_affinity`` and ``forward`` in
    zzangjinsun/NLSPN_ECCV20 src/model/nlspnmodel.py), with torchvision's ``deform_conv2d`` standing in for the
    DCNv2 extension (same offset layout and sampling)."""
    from torchvision.ops import deform_conv2d

    init, guidance, conf, sparse = inputs.values()
    b, _, h, w = guidance.shape
    o1, o2, aff = torch.chunk(prop.conv_offset_aff(guidance), 3, dim=1)
    offset = torch.cat((o1, o2), dim=1).view(b, 8, 2, h, w)
    offset = torch.cat((offset[:, :4], torch.zeros(b, 1, 2, h, w), offset[:, 4:]), dim=1).view(b, 18, h, w)
    aff = torch.tanh(aff) / (prop.aff_scale_const + 1e-8)
    confs = []
    for k in range(9):
        if k == 4:
            continue
        offset_k = offset[:, 2 * k : 2 * k + 2].detach()  # a view: the legacy shift below also moves `offset`
        if legacy:
            offset_k[:, 0] += k // 3 - 1
            offset_k[:, 1] += k % 3 - 1
        confs.append(deform_conv2d(conf, offset_k, torch.ones(1, 1, 1, 1)))  # 1x1 kernel, no padding
    aff = aff * torch.cat(confs, dim=1)
    abs_sum = aff.abs().sum(dim=1, keepdim=True) + 1e-4
    abs_sum[abs_sum < 1.0] = 1.0
    aff = aff / abs_sum
    aff = torch.cat((aff[:, :4], 1.0 - aff.sum(dim=1, keepdim=True), aff[:, 4:]), dim=1)
    mask = (sparse > 0).float()
    depth = init
    for _ in range(prop.steps):
        depth = (1.0 - mask) * depth + mask * sparse
        depth = deform_conv2d(depth, offset, torch.ones(1, 1, 3, 3), padding=1, mask=aff)
    return depth


@pytest.mark.parametrize("confidence_sampling", ["offset", "legacy"])
def test_upstream_modes_reproduce_upstream_code(confidence_sampling):
    # The reference below is upstream with --preserve_input.
    prop = NonLocalPropagation(steps=4, confidence_sampling=confidence_sampling, preserve_input=True)
    perturb_propagation(prop)
    inputs = propagation_inputs(h=12, w=15, seed=1)
    with torch.no_grad():
        ours = prop(**inputs).depth
        theirs = upstream_propagation(prop, inputs, legacy=confidence_sampling == "legacy")
        neighbour = NonLocalPropagation(steps=4, confidence_sampling="neighbour", preserve_input=True)
        neighbour.load_state_dict(prop.state_dict())
        other = neighbour(**inputs).depth
    torch.testing.assert_close(ours, theirs, rtol=1e-5, atol=1e-4)
    assert (other - theirs).abs().max() > 1e-2  # the modes differ, so the comparison above is meaningful


def test_impls_give_same_gradients():
    inputs = propagation_inputs(h=10, w=12)
    grads = []
    for impl in ("grid_sample", "deform_conv"):
        prop = NonLocalPropagation(steps=3, impl=impl)
        perturb_propagation(prop)
        g = inputs["guidance"].clone().requires_grad_(True)
        out = prop(inputs["init_depth"], g, inputs["confidence"], inputs["sparse_depth"]).depth
        (out * torch.linspace(-1, 1, out.numel()).view_as(out)).sum().backward()
        grads.append((g.grad, prop.conv_offset_aff.weight.grad, prop.aff_scale_const.grad))
    for a, b in zip(*grads, strict=True):
        assert a.abs().max() > 0
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("impl", ["grid_sample", "deform_conv"])
def test_sample_neighbours_borders(impl):
    x = torch.arange(1.0, 13.0).view(1, 1, 3, 4)
    d = torch.zeros(1, 8, 2, 3, 4)
    taps = kernel_taps(3)
    # Neighbour j sits at p + displacement_j; set each neighbour's displacement explicitly (dy, dx).
    cases = [
        (-0.5, 0.0),
        (0.0, -1.0),
        (2.5, 0.0),
        (0.0, 3.0),
        (0.25, 0.5),
        (-1.0, 0.0),
        (3.0, 0.0),
        (0.0, -0.75),
    ]
    for j, (dy, dx) in enumerate(cases):
        d[0, j, 0], d[0, j, 1] = dy, dx
    out = sample_neighbours(x, d, impl)
    img = x[0, 0].numpy().astype(np.float64)
    for j, (dy, dx) in enumerate(cases):
        expected = [[bilinear(img, y + dy, xx + dx) for xx in range(4)] for y in range(3)]
        np.testing.assert_allclose(out[0, j].numpy(), expected, atol=1e-5, err_msg=f"displacement {(dy, dx)}")
    assert taps.shape == (8, 2)
    # Spot checks derived by hand: half a pixel above row 0 reads half of row 0; a full pixel outside reads 0.
    assert out[0, 0, 0, 1].item() == pytest.approx(0.5 * 2.0)
    assert out[0, 5, 0].abs().max() == 0 and out[0, 6].abs().max() == 0


def test_preserve_input_resets_valid_pixels_before_every_step():
    inputs = propagation_inputs(h=10, w=12)
    prop = NonLocalPropagation(steps=3, preserve_input=True)
    perturb_propagation(prop)
    valid = inputs["sparse_depth"] > 0
    with torch.no_grad():
        out = prop(**inputs).depth
        # The initial depth is overwritten at valid pixels before the first step: changing it there is a no-op.
        changed = dict(
            inputs, init_depth=torch.where(valid, inputs["init_depth"] + 50.0, inputs["init_depth"])
        )
        assert torch.equal(prop(**changed).depth, out)
        # Three steps = three single steps, each starting from the sparse input at valid pixels.
        one = NonLocalPropagation(steps=1, preserve_input=True)
        one.load_state_dict(prop.state_dict())
        depth = inputs["init_depth"]
        for _ in range(3):
            depth = one(**dict(inputs, init_depth=depth)).depth
        torch.testing.assert_close(depth, out)
        # Without preservation the initial depth at valid pixels does matter.
        free = NonLocalPropagation(steps=3, preserve_input=False)
        free.load_state_dict(prop.state_dict())
        assert not torch.allclose(free(**changed).depth, free(**inputs).depth)


def test_zero_initialised_propagation_is_identity_with_preserved_input():
    inputs = propagation_inputs()
    with torch.no_grad():
        out = NonLocalPropagation(steps=5, preserve_input=True)(**inputs).depth
    valid = inputs["sparse_depth"] > 0
    # Upstream's zero init: all neighbour affinities 0, centre 1; the output is the initial depth with the
    # sparse input written in, exactly.
    torch.testing.assert_close(
        out, torch.where(valid, inputs["sparse_depth"], inputs["init_depth"]), rtol=0, atol=0
    )


@pytest.mark.parametrize("affinity", ["TGASS", "ASS", "AS", "TC"])
def test_affinity_normalisation_properties(affinity):
    g = torch.Generator().manual_seed(0)
    logits = 5 * torch.randn(3, 8, 6, 6, generator=g)
    conf = torch.rand(3, 8, 6, 6, generator=g)
    gamma = 8.0 if affinity == "TC" else 0.5 * 8 if affinity == "TGASS" else 1.0
    aff, centre = normalize_affinity(logits, affinity, gamma, conf)
    abs_sum = aff.abs().sum(dim=1)
    torch.testing.assert_close(centre[:, 0], 1 - aff.sum(dim=1))
    if affinity in ("TGASS", "ASS"):
        assert (abs_sum <= 1).all()
    if affinity == "AS":  # normalised to 1 exactly, up to upstream's +1e-4 in the denominator
        torch.testing.assert_close(abs_sum, torch.ones_like(abs_sum), atol=1e-4, rtol=0)
    if affinity == "TC":  # no normalisation: tanh(a) * conf / 8
        torch.testing.assert_close(aff, torch.tanh(logits) * conf / 8)
    if affinity == "TGASS":  # |a| < 1/gamma each, so sum|a| < 8/4 = 2; large logits make the clamp act
        assert ((abs_sum - 1).abs() < 1e-4).any() and (abs_sum < 0.99).any()


def test_learnable_gamma_only_for_tgass():
    assert isinstance(NonLocalPropagation(affinity="TGASS").aff_scale_const, nn.Parameter)
    for affinity, value in (("TC", 8.0), ("AS", 1.0), ("ASS", 1.0)):
        prop = NonLocalPropagation(affinity=affinity)
        assert not isinstance(prop.aff_scale_const, nn.Parameter)
        assert prop.aff_scale_const.item() == value
        assert "aff_scale_const" in prop.state_dict()


def test_propagation_argument_errors():
    with pytest.raises(ValueError, match="affinity"):
        NonLocalPropagation(affinity="softmax")
    with pytest.raises(ValueError, match="impl"):
        NonLocalPropagation(impl="cuda")
    with pytest.raises(ValueError, match="confidence_sampling"):
        NonLocalPropagation(confidence_sampling="center")
    with pytest.raises(ValueError, match="kernel_size"):
        NonLocalPropagation(kernel_size=4)
    prop = NonLocalPropagation(steps=1, preserve_input=True)
    inputs = propagation_inputs()
    with pytest.raises(ValueError, match="confidence"):
        prop(**dict(inputs, confidence=None))
    with pytest.raises(ValueError, match="sparse_depth"):
        prop(**dict(inputs, sparse_depth=None))
    with pytest.raises(ValueError, match="sparse_depth"):
        prop(**dict(inputs, sparse_depth=inputs["sparse_depth"][:, :, :-1]))
    with pytest.raises(ValueError, match="guidance"):
        prop(**dict(inputs, guidance=inputs["guidance"][:, :4]))


class _PropagationOnly(nn.Module):
    def __init__(self, prop: NonLocalPropagation) -> None:
        super().__init__()
        self.prop = prop

    def forward(
        self, init_depth: Tensor, guidance: Tensor, confidence: Tensor, sparse_depth: Tensor
    ) -> Tensor:
        return self.prop(init_depth, guidance, confidence, sparse_depth).depth


@pytest.mark.parametrize("impl", ["deform_conv"])
def test_propagation_onnx_runs_in_onnxruntime(tmp_path, impl):
    """The DCN formulation exports to ONNX DeformConv (opset >= 19) and matches in onnxruntime, dynamic batch.
    (The whole network, with the default grid_sample formulation, is exported by the shared tests above.)"""
    import onnx

    prop = NonLocalPropagation(steps=6, impl=impl)
    perturb_propagation(prop)
    path = export_onnx(_PropagationOnly(prop), propagation_inputs(h=20, w=24), tmp_path / "prop.onnx",
                       output_name="depth", opset=20)  # fmt: skip
    expected_op = {"deform_conv": "DeformConv", "grid_sample": "GridSample"}[impl]
    assert expected_op in {node.op_type for node in onnx.load(str(path)).graph.node}
    report = verify_onnx(path, _PropagationOnly(prop), propagation_inputs(b=3, h=20, w=24, seed=3), atol=1e-5,
                         rtol=1e-4, measure_latency=False)  # fmt: skip
    assert report.output_shape == (3, 1, 20, 24)


# ---------------------------------------------------------------------------------------------------------------
# Loss


def test_l1_l2_loss_matches_per_pixel_computation():
    g = torch.Generator().manual_seed(0)
    pred = 150 * torch.rand(3, 1, 5, 6, generator=g)
    gt = 150 * torch.rand(3, 1, 5, 6, generator=g) * (torch.rand(3, 1, 5, 6, generator=g) < 0.5)
    gt[2] = 0.0  # a sample without ground truth
    per_sample = []
    for b in range(2):
        pairs = [(min(p, 120.0), min(t, 120.0)) for p, t in zip(pred[b].flatten().tolist(), gt[b].flatten().tolist(),
                                                                strict=True) if t > 1e-4]  # fmt: skip
        l1 = sum(abs(p - t) for p, t in pairs) / len(pairs)
        l2 = sum((p - t) ** 2 for p, t in pairs) / len(pairs)
        per_sample.append(0.5 * l1 + 2.0 * l2)
    loss_sum = L1L2Loss(max_depth=120.0, l1_weight=0.5, l2_weight=2.0, reduction="sum")(pred, gt)
    loss_mean = L1L2Loss(max_depth=120.0, l1_weight=0.5, l2_weight=2.0)(pred, gt)
    loss_none = L1L2Loss(max_depth=120.0, l1_weight=0.5, l2_weight=2.0, reduction="none")(
        pred[:, 0], gt[:, 0]
    )
    assert loss_sum.item() == pytest.approx(sum(per_sample), rel=1e-5)  # upstream: summed over the batch
    assert loss_mean.item() == pytest.approx(
        sum(per_sample) / 2, rel=1e-5
    )  # mean over samples with ground truth
    np.testing.assert_allclose(loss_none.numpy(), [*per_sample, 0.0], rtol=1e-5)
    assert NLSPNLoss is L1L2Loss


def test_l1_l2_loss_gradients_and_edge_cases():
    pred = torch.tensor([[[[5.0, 130.0, 7.0, -1.0]]]], requires_grad=True)
    gt = torch.tensor([[[[4.0, 125.0, 0.0, 2.0]]]])
    loss = L1L2Loss(max_depth=120.0)(pred, gt)
    loss.backward()
    # pixel 0: error 1; pixel 1: both clamp to 120; pixel 2: no ground truth; pixel 3: pred clamps to 0, error 2.
    assert loss.item() == pytest.approx((1 + 0 + 2) / 3 + (1 + 0 + 4) / 3)
    assert pred.grad[0, 0, 0, 1] == 0 and pred.grad[0, 0, 0, 2] == 0 and pred.grad[0, 0, 0, 3] == 0
    assert pred.grad[0, 0, 0, 0] > 0
    empty = L1L2Loss()(pred, torch.zeros_like(gt))
    assert empty.item() == 0 and torch.isfinite(torch.autograd.grad(empty, pred)[0]).all()
    l1, l2, valid = masked_l1_l2(pred.detach(), gt)
    assert (l1.item(), l2.item(), valid.item()) == (pytest.approx(1.0), pytest.approx(5 / 3), True)
    with pytest.raises(ValueError, match="same shape"):
        L1L2Loss()(pred, gt[..., :2])
    with pytest.raises(ValueError, match="reduction"):
        L1L2Loss(reduction="avg")
    with pytest.raises(ValueError, match="pred"):
        L1L2Loss()(torch.zeros(1, 2, 3, 3), torch.zeros(1, 2, 3, 3))


def test_propagation_is_fp32_under_bf16_autocast():
    """Mixed precision leaves the propagation in float32: the output under CPU bf16 autocast equals the float32
    one to float32 tolerance (run in bf16, 18 steps at 512 wide drift by metres)."""
    prop = NonLocalPropagation(steps=18)
    perturb_propagation(prop)
    inputs = {k: v * 10 if k == "init_depth" else v for k, v in propagation_inputs(b=1, h=16, w=512).items()}
    with torch.no_grad():
        reference = prop(**inputs).depth
        with torch.autocast("cpu", dtype=torch.bfloat16):
            mixed = prop(**inputs).depth
            unguarded = prop._propagate(**inputs).depth  # what autocast would do without the float32 guard
            half_inputs = prop(**{k: v.bfloat16() for k, v in inputs.items()}).depth
    assert mixed.dtype == torch.float32 and half_inputs.dtype == torch.float32
    torch.testing.assert_close(mixed, reference, rtol=1e-5, atol=1e-5)
    assert (unguarded.float() - reference).abs().max() > 1e-2  # so the comparison above discriminates


def test_nlspn_output_is_fp32_under_bf16_autocast():
    model = NLSPN(encoder_name="resnet18", prop_steps=3).eval()
    image, sparse = torch.randn(1, 3, 32, 48), torch.zeros(1, 1, 32, 48)
    sparse[..., ::5, ::3] = 20.0
    with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16):
        out = model.forward_with_aux(image, sparse)
    assert out["guidance"].dtype == torch.bfloat16  # the network itself does run in bf16
    assert out["depth"].dtype == torch.float32 and torch.isfinite(out["depth"]).all()
