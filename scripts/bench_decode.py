"""Decode speed of the per-frame image files, one thread: PIL, torchvision.io, OpenCV (if installed), codecs.

Reads the cube faces of one frame of a dataset (``--root``), or of a synthetic 512^2 one (gradients and noise), in every
encoding the layout allows (RGB: PNG and JPEG as the writer encodes them; depth: 16-bit PNG and ``.npy``; labels:
8-bit PNG), decodes each file with each library and reports the minimum CPU ms per face over ``--repeats`` rounds
(the libraries take turns within a round), and checks every decoder's pixels against PIL's (bit-exact). The
``codecs reader`` column is what the dataset calls (for depth, including the conversion to float32 metres).

    python scripts/bench_decode.py --root /tmp/afb_bench512 --repeats 15
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from airfisheye_bench.io import DatasetReader, codecs

Decoder = Callable[[Path], np.ndarray]


def pil(path: Path) -> np.ndarray:
    """PIL: open, decode, copy out (what the codecs did before)."""
    with Image.open(path) as img:
        return np.asarray(img).copy()


def torchvision_io(path: Path) -> np.ndarray:
    """torchvision.io: read the file, decode (PNG or JPEG by signature), channels last."""
    from torchvision.io import ImageReadMode, decode_image, read_file

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # deprecated since torchvision 0.29
        x = decode_image(read_file(str(path)), ImageReadMode.UNCHANGED)
    return x.permute(1, 2, 0).numpy() if x.shape[0] > 1 else x[0].numpy()


def opencv(path: Path) -> np.ndarray:
    """OpenCV ``imread`` (BGR flipped to RGB; not a dependency of the project)."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    return img[..., ::-1] if img.ndim == 3 else img


def faces(root: str | None, out: Path) -> dict[str, list[Path]]:
    """The five faces of one frame in every encoding, written under ``out``: ``{encoding: [paths]}``."""
    if root is None:  # smooth gradients plus a little noise, roughly like rendered faces
        rng = np.random.default_rng(0)
        ramp = np.add.outer(np.arange(512), np.arange(512)) / 4.0
        rgb = np.stack([ramp, ramp.T, 255 - ramp], -1) % 256 + rng.integers(0, 8, (5, 512, 512, 3))
        rgb = np.clip(rgb, 0, 255).astype(np.uint8)
        depth = (5.0 + ramp / 8.0 + rng.normal(0.0, 0.05, (5, 512, 512))).astype(np.float32)
        seg = (rgb[..., 0] // 16).astype(np.uint8)
    else:
        reader = DatasetReader(root)
        sid = reader.split(reader.split_names[0])[0]
        rgb, depth, seg = (reader.cubemap(sid, m) for m in ("rgb", "depth", "seg"))
    sources = {  # encoding: (writer, arrays, suffix)
        "rgb png": (codecs.write_rgb, rgb, ".png"),
        "rgb jpg": (codecs.write_rgb, rgb, ".jpg"),
        "depth png16": (codecs.write_depth, depth, ".png"),
        "depth npy": (codecs.write_depth, depth, ".npy"),
        "seg png": (codecs.write_label, seg, ".png"),
    }
    files: dict[str, list[Path]] = {}
    for key, (write, arrays, suffix) in sources.items():
        files[key] = [out / f"{key.replace(' ', '_')}_{f}{suffix}" for f in range(5)]
        for path, array in zip(files[key], arrays, strict=True):
            write(path, array)
    return files


def readers() -> dict[str, Decoder]:
    """The ``codecs`` reader of each encoding (what the dataset calls)."""
    return {
        "rgb png": codecs.read_rgb,
        "rgb jpg": codecs.read_rgb,
        "depth png16": codecs.read_depth,
        "depth npy": codecs.read_depth,
        "seg png": codecs.read_label,
    }


def decoders() -> dict[str, Decoder]:
    """Every decoder available here."""
    out: dict[str, Decoder] = {"PIL": pil, "torchvision.io": torchvision_io}
    try:
        import cv2

        cv2.setNumThreads(1)
        out["OpenCV"] = opencv
    except ImportError:
        pass
    return out


def batch(decode: Decoder, paths: list[Path]) -> Callable[[], list[np.ndarray]]:
    """A function decoding every file of ``paths`` with ``decode``."""
    return lambda: [decode(p) for p in paths]


def min_ms_per_file(fns: dict[str, Callable[[], object]], repeats: int, n_files: int) -> dict[str, float]:
    """Minimum CPU ms per file of each function (which decodes ``n_files`` files), taking turns per round."""
    best = dict.fromkeys(fns, math.inf)
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.process_time()
            fn()
            best[name] = min(best[name], time.process_time() - t0)
    return {name: t / n_files * 1e3 for name, t in best.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--root", default=None, help="dataset whose first frame's faces are used")
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        files = faces(args.root, Path(tmp))
        size = codecs.read_rgb(files["rgb png"][0]).shape[0]
        names = [*decoders(), "codecs reader"]
        print(f"faces {size}^2, CPU ms per face (min of {args.repeats}); bit-exact = same pixels as PIL\n")
        print("| file | KB | " + " | ".join(names) + " | bit-exact |")
        print("|---|---|" + "---|" * (len(names) + 1))
        for key, paths in files.items():
            fns = {} if key == "depth npy" else {n: batch(d, paths) for n, d in decoders().items()}
            fns["codecs reader"] = batch(readers()[key], paths)
            times = min_ms_per_file(fns, args.repeats, len(paths))
            exact = key == "depth npy" or all(
                np.array_equal(d(p), pil(p)) for d in decoders().values() for p in paths
            )
            kb = np.mean([p.stat().st_size for p in paths]) / 1024
            cells = " | ".join(f"{times[n]:.2f}" if n in times else "-" for n in names)
            print(f"| {key} | {kb:.0f} | {cells} | {exact} |")


if __name__ == "__main__":
    main()
