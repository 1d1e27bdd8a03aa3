"""Shared tests for every model of the zoo (in the style of smp's ``tests/helpers/model_tester.py``).

A model's test file subclasses :class:`BaseModelTester` and sets a few class attributes::

    class TestDeepLabV3Plus(BaseModelTester):
        model_name = "deeplabv3plus"
        task = "seg"
        model_kwargs = {"encoder_name": "resnet18", "num_classes": 5}
        output_stride = 16

Every test builds the model through ``models.create_model(model_name, **model_kwargs)`` and checks the calling
convention of ``models/__init__.py``: named inputs (``image`` and, for completion, ``sparse_depth``), ``forward``
returning the primary output, ``forward_with_aux`` returning a dict, clear ``ValueError`` on bad input, and an
ONNX export (dynamic batch) that ONNX Runtime reproduces. ``paper_kwargs`` enables the full-size ``slow`` tests.

A tester whose ``model_kwargs`` hold ``camera_input="rays"`` feeds the ray map (``rays``, of a fisheye lens at the
input's size) and checks the camera input's contract too: a missing or misshapen ray map is refused, and the ray path
starts at zero (a rays model holding a plain model's weights gives its output, whatever the rays).
"""

from __future__ import annotations

import math
import re
from typing import ClassVar

import pytest
import torch
from torch import Tensor, nn

import models
from airfisheye_bench.export import export_onnx, verify_onnx
from airfisheye_bench.export.deploy import parity_tolerance
from airfisheye_bench.geometry.cameras import ideal_camera
from airfisheye_bench.geometry.ray_maps import ray_map
from airfisheye_bench.runs.deployment import read_onnx_metadata

_PRIMARY_KEY = {"seg": "logits", "depth": "depth", "completion": "depth"}

#: Models that a default-suite test exports through ``airfisheye-export`` and runs in ONNX Runtime: model name -> that
#: test. Their ONNX tests here (the same checks on another configuration) are ``slow`` (``tests/models/conftest.py``),
#: so that the default suite exports each model once. NLSPN is not one: its tester perturbs the propagation, which a
#: seconds-long run leaves close to its zero initialisation.
DEPLOYED_BY = {
    "deeplabv3plus": "tests/export/test_deploy.py::test_seg_export_has_a_dynamic_batch",
    "adabins": "tests/export/test_deploy.py::test_depth_tasks_export_through_the_cli",
}


class BaseModelTester:
    """Mixin of model tests; subclasses set the class attributes below (only ``model_name`` and ``task`` are
    required)."""

    #: Registry name passed to ``models.create_model``.
    model_name: ClassVar[str] = ""
    #: ``"seg"``, ``"depth"`` or ``"completion"``.
    task: ClassVar[str] = ""
    #: Constructor kwargs of a tiny configuration (fast on CPU) used by the default tests.
    model_kwargs: ClassVar[dict] = {}
    #: Input sizes ``(H, W)`` for the shape test; the first one is also used by the other tests.
    input_sizes: ClassVar[tuple[tuple[int, int], ...]] = ((64, 64), (64, 128), (96, 64))
    #: H and W must be multiples of this (1 if the model takes any size).
    output_stride: ClassVar[int] = 32
    in_channels: ClassVar[int] = 3
    #: Keys ``forward_with_aux`` must return besides the primary output.
    aux_keys: ClassVar[tuple[str, ...]] = ()
    #: Regexes of parameter names allowed to get no (or zero) gradient from the primary output.
    params_without_grad: ClassVar[tuple[str, ...]] = ()
    #: ONNX parity tolerances; ``None`` picks the task default (seg: abs 1e-4; depth: rel 1e-3).
    onnx_atol: ClassVar[float | None] = None
    onnx_rtol: ClassVar[float | None] = None
    #: Whether the ONNX export with symbolic H and W is expected to work (checked by a ``slow`` test).
    supports_dynamic_spatial: ClassVar[bool] = True
    #: Kwargs of the paper configuration and its input size, for the ``slow`` tests (``None`` skips them).
    paper_kwargs: ClassVar[dict | None] = None
    paper_input_size: ClassVar[tuple[int, int]] = (512, 512)

    # ------------------------------------------------------------------ helpers

    @property
    def primary_key(self) -> str:
        return _PRIMARY_KEY[self.task]

    @property
    def takes_rays(self) -> bool:
        return self.model_kwargs.get("camera_input", "none") == "rays"

    @property
    def input_names(self) -> list[str]:
        names = ["image", "sparse_depth"] if self.task == "completion" else ["image"]
        return [*names, "rays"] if self.takes_rays else names

    @property
    def out_channels(self) -> int:
        return self.model_kwargs.get("num_classes", 13) if self.task == "seg" else 1

    def make_model(self, seed: int = 0, **overrides) -> nn.Module:
        torch.manual_seed(seed)
        return models.create_model(self.model_name, **{**self.model_kwargs, **overrides})

    def make_inputs(self, batch: int, size: tuple[int, int], seed: int = 0) -> dict[str, Tensor]:
        """Normalised-image-like noise and, for completion, ~5 % of pixels with a depth in [1, 100] m."""
        g = torch.Generator().manual_seed(seed)
        h, w = size
        inputs = {"image": torch.randn(batch, self.in_channels, h, w, generator=g)}
        if self.task == "completion":
            depth = 1.0 + 99.0 * torch.rand(batch, 1, h, w, generator=g)
            inputs["sparse_depth"] = depth * (torch.rand(batch, 1, h, w, generator=g) < 0.05)
        if self.takes_rays:
            inputs["rays"] = fisheye_rays(batch, size)
        return inputs

    def tolerances(self) -> tuple[float, float]:
        # The export's own contract (the task spec's parity rule): segmentation logits within 1e-4, depth within
        # 1e-4 m + 1e-3 relative. A stricter floor fails on round-off: an untrained NLSPN outputs depths of ~1e-4 m,
        # where a 1.4e-6 m difference between ONNX Runtime and PyTorch is 1.5 % relative.
        atol, rtol = parity_tolerance(self.task)
        return (self.onnx_atol if self.onnx_atol is not None else atol), (
            self.onnx_rtol if self.onnx_rtol is not None else rtol
        )

    def check_output(self, out: Tensor, batch: int, size: tuple[int, int]) -> None:
        assert isinstance(out, Tensor), f"forward must return a Tensor, got {type(out).__name__}"
        assert out.shape == (batch, self.out_channels, *size)
        assert torch.isfinite(out).all()
        if self.task != "seg":
            assert (out >= 0).all(), "depth must be non-negative"

    # ------------------------------------------------------------------ registry and shapes

    def test_registered_for_task(self):
        assert self.model_name in models.list_models(self.task)
        assert models.model_task(self.model_name) == self.task

    def test_forward_shapes(self):
        model = self.make_model().eval()
        with torch.no_grad():
            for size in self.input_sizes:
                assert size[0] % self.output_stride == 0 and size[1] % self.output_stride == 0, size
                self.check_output(model(**self.make_inputs(2, size)), 2, size)

    def test_backward_gives_finite_nonzero_grads(self):
        model = self.make_model().train()
        inputs = self.make_inputs(2, self.input_sizes[0])
        out = model(**inputs)
        # A random projection of the output, so no parameter's gradient cancels by symmetry (as a plain sum
        # would for softmax-normalised outputs).
        weights = torch.randn(out.shape, generator=torch.Generator().manual_seed(1))
        (out * weights).sum().backward()
        exempt = [re.compile(p) for p in self.params_without_grad]
        missing, not_finite, zero = [], [], []
        for name, p in model.named_parameters():
            if not p.requires_grad or any(r.search(name) for r in exempt):
                continue
            if p.grad is None:
                missing.append(name)
            elif not torch.isfinite(p.grad).all():
                not_finite.append(name)
            elif not p.grad.abs().gt(0).any():
                zero.append(name)
        assert not missing, f"parameters without grad: {missing}"
        assert not not_finite, f"parameters with non-finite grad: {not_finite}"
        assert not zero, f"parameters with all-zero grad: {zero}"

    def test_eval_is_deterministic_and_batch_independent(self):
        model = self.make_model().eval()
        inputs = self.make_inputs(2, self.input_sizes[0])
        with torch.no_grad():
            first, second = model(**inputs), model(**inputs)
            alone = model(**{k: v[1:] for k, v in inputs.items()})
        assert torch.equal(first, second)
        # Eval mode must not mix samples (e.g. batch statistics): sample 1 alone gives the same output.
        torch.testing.assert_close(alone, first[1:], atol=1e-4, rtol=1e-4)

    def test_forward_with_aux(self):
        model = self.make_model().eval()
        inputs = self.make_inputs(2, self.input_sizes[0])
        with torch.no_grad():
            aux = model.forward_with_aux(**inputs)
            out = model(**inputs)
        assert isinstance(aux, dict)
        expected = {self.primary_key, *self.aux_keys}
        assert expected <= set(aux), f"forward_with_aux keys {sorted(aux)} lack {sorted(expected - set(aux))}"
        torch.testing.assert_close(aux[self.primary_key], out)

    # ------------------------------------------------------------------ input validation

    def test_wrong_input_channels_raises(self):
        model = self.make_model().eval()
        inputs = self.make_inputs(1, self.input_sizes[0])
        inputs["image"] = torch.randn(1, self.in_channels + 1, *self.input_sizes[0])
        with pytest.raises(ValueError, match=rf"image.*{self.in_channels}"):
            model(**inputs)
        inputs["image"] = torch.randn(self.in_channels, *self.input_sizes[0])  # no batch dim
        with pytest.raises(ValueError, match="image"):
            model(**inputs)

    def test_size_not_divisible_by_output_stride_raises(self):
        if self.output_stride == 1:
            pytest.skip("model takes any input size")
        h, w = self.input_sizes[0]
        bad = (h + self.output_stride // 2 + 1, w + 1)
        pad = tuple(math.ceil(s / self.output_stride) * self.output_stride for s in bad)
        model = self.make_model().eval()
        with pytest.raises(ValueError, match=str(self.output_stride)) as err:
            model(**self.make_inputs(1, bad))
        message = str(err.value)
        assert str(pad[0]) in message and str(pad[1]) in message, (
            f"message should say to pad to {pad}: {message}"
        )

    def test_a_missing_or_misshapen_ray_map_is_refused(self):
        model = self.make_model().eval()
        inputs = self.make_inputs(2, self.input_sizes[0])
        h, w = self.input_sizes[0]
        if not self.takes_rays:
            with pytest.raises(ValueError, match="camera_input=none and takes no rays"):
                model(**inputs, rays=fisheye_rays(2, (h, w)))
            return
        with pytest.raises(ValueError, match="camera_input=rays and needs rays"):
            model(**{k: v for k, v in inputs.items() if k != "rays"})
        for bad in (inputs["rays"][:, :3], inputs["rays"][:1], fisheye_rays(2, (h // 2, w))):
            with pytest.raises(ValueError, match=r"rays must have shape"):
                model(**{**inputs, "rays": bad})

    def test_the_ray_path_starts_at_zero(self):
        """A rays model holding a plain model's weights, its ray weights as built, gives the plain model's output
        whatever the ray map: the camera input is added to the model, nothing of it replaced."""
        if not self.takes_rays:
            pytest.skip("the model takes no rays")
        plain = self.make_model(camera_input="none").eval()
        model = self.make_model(seed=1).eval()
        load_overlapping(model, plain.state_dict())
        inputs = self.make_inputs(2, self.input_sizes[0])
        noise = torch.randn(inputs["rays"].shape, generator=torch.Generator().manual_seed(2))
        with torch.no_grad():
            expected = plain(**{k: v for k, v in inputs.items() if k != "rays"})
            torch.testing.assert_close(model(**inputs), expected, atol=1e-5, rtol=1e-5)
            torch.testing.assert_close(model(**{**inputs, "rays": noise}), expected, atol=1e-5, rtol=1e-5)

    def test_wrong_sparse_depth_shape_raises(self):
        if self.task != "completion":
            pytest.skip("only completion models take sparse_depth")
        model = self.make_model().eval()
        inputs = self.make_inputs(2, self.input_sizes[0])
        h, w = self.input_sizes[0]
        for bad in (
            inputs["sparse_depth"][:, 0],
            torch.zeros(2, 2, h, w),
            torch.zeros(2, 1, h // 2, w),
            torch.zeros(1, 1, h, w),
        ):
            with pytest.raises(ValueError, match="sparse_depth"):
                model(**{**inputs, "sparse_depth": bad})

    # ------------------------------------------------------------------ ONNX

    @pytest.fixture(scope="class")
    @classmethod
    def exported(cls, tmp_path_factory) -> tuple[nn.Module, str]:
        # A classmethod: the fixture runs once per class, and each test method gets a new instance.
        case = cls()
        model = case.make_model().eval()
        path = tmp_path_factory.mktemp("onnx") / f"{case.model_name}.onnx"
        export_onnx(
            model,
            case.make_inputs(2, case.input_sizes[0]),
            path,
            output_name=case.primary_key,
            metadata={"task": case.task, "model": case.model_name},
        )
        return model, str(path)

    @pytest.mark.integration
    @pytest.mark.parametrize("batch", [2, 3])
    def test_onnx_matches_pytorch_with_dynamic_batch(self, exported, batch):
        model, path = exported
        atol, rtol = self.tolerances()
        report = verify_onnx(
            path,
            model,
            self.make_inputs(batch, self.input_sizes[0], seed=batch),
            atol=atol,
            rtol=rtol,
            measure_latency=False,
        )
        assert report.output_shape == (batch, self.out_channels, *self.input_sizes[0])

    @pytest.mark.integration
    def test_onnx_names_and_metadata(self, exported):
        import onnx

        _, path = exported
        graph = onnx.load(path).graph
        assert sorted(i.name for i in graph.input) == sorted(self.input_names)
        assert [o.name for o in graph.output] == [self.primary_key]
        assert read_onnx_metadata(path) == {"task": self.task, "model": self.model_name}

    @pytest.mark.slow
    def test_onnx_dynamic_spatial(self, tmp_path):
        if not self.supports_dynamic_spatial:
            pytest.skip("model is exported at a fixed size")
        model = self.make_model().eval()
        path = export_onnx(
            model,
            self.make_inputs(2, self.input_sizes[0]),
            tmp_path / "dyn.onnx",
            output_name=self.primary_key,
            dynamic_spatial=True,
        )
        atol, rtol = self.tolerances()
        # One image per size: the batch axis is checked by test_onnx_matches_pytorch_with_dynamic_batch (and a batch
        # of 1 against an export at 2 still exercises it).
        for i, size in enumerate(self.input_sizes):
            report = verify_onnx(
                path, model, self.make_inputs(1, size, seed=i), atol=atol, rtol=rtol, measure_latency=False
            )
            assert report.output_shape == (1, self.out_channels, *size)

    # ------------------------------------------------------------------ paper configuration (slow)

    def _paper_model(self) -> nn.Module:
        if self.paper_kwargs is None:
            pytest.skip("no paper configuration for this model")
        torch.manual_seed(0)
        return models.create_model(self.model_name, **self.paper_kwargs)

    @pytest.mark.slow
    def test_paper_config_forward_backward(self):
        model = self._paper_model().train()
        inputs = self.make_inputs(2, self.paper_input_size)
        out = model(**inputs)
        channels = self.paper_kwargs.get("num_classes", 13) if self.task == "seg" else 1
        assert out.shape == (2, channels, *self.paper_input_size)
        out.float().mean().backward()
        grads = [p.grad for p in model.parameters() if p.requires_grad]
        assert all(g is not None and torch.isfinite(g).all() for g in grads)

    @pytest.mark.slow
    def test_paper_config_onnx(self, tmp_path):
        model = self._paper_model().eval()
        path = export_onnx(
            model,
            self.make_inputs(2, self.paper_input_size),
            tmp_path / "paper.onnx",
            output_name=self.primary_key,
        )
        atol, rtol = self.tolerances()
        report = verify_onnx(
            path,
            model,
            self.make_inputs(1, self.paper_input_size, seed=3),  # one image at 512^2: other batches, above
            atol=atol,
            rtol=rtol,
            measure_latency=False,
        )
        assert report.output_shape[0] == 1


def fisheye_rays(batch: int, size: tuple[int, int]) -> Tensor:
    """The ray map ``[batch, 4, H, W]`` of a 190 deg equidistant lens filling an ``H x W`` image."""
    h, w = size
    return ray_map(ideal_camera(w, h, fov_deg=190.0))[None].expand(batch, -1, -1, -1).contiguous()


def load_overlapping(model: nn.Module, state: dict[str, Tensor]) -> None:
    """Copy ``state`` into ``model``: a tensor of the same shape whole, a widened one (more input channels, or a
    depthwise convolution's more groups) into its leading part, leaving the rest as built."""
    own = model.state_dict()
    assert set(own) == set(state), sorted(set(own) ^ set(state))
    with torch.no_grad():
        for key, value in state.items():
            target = own[key]
            target[tuple(slice(0, n) for n in value.shape)].copy_(value)
