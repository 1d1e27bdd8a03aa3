"""The small commands: inspect, transcode, leaderboard, export, predict and the synthetic generator.

Each takes ``key=value`` arguments composed onto ``configs/<command>.yaml`` (:mod:`airfisheye_bench.cli.options`:
typed, struct mode, one ``--help``) and calls its library function. A bad argument ends in one line naming the key
(:class:`~airfisheye_bench.errors.ConfigError` under :func:`~airfisheye_bench.errors.report_user_errors`: exit
status 2); each function returns the command's exit status otherwise.

Each command imports its library when it runs, not when this module loads: ``--help`` and a bad option are answered
in well under a second, where importing the libraries (torch, Lightning, ONNX Runtime) takes 3 to 9 s.

Example:
    >>> inspect(["root=/nowhere", "deep=maybe"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    SystemExit: 2
    >>> print(render_help(INSPECT))  # doctest: +NORMALIZE_WHITESPACE
    Report missing or malformed files of a dataset, or the rings and removed returns of LiDAR scan files (exit status 1 when there are problems).
    <BLANKLINE>
    usage: airfisheye-inspect root=DIR [key=value ...]
    <BLANKLINE>
    options (key=value; defaults from configs/inspect.yaml):
      root            str        (required)  the dataset root folder (it holds dataset.yaml), or a folder / file of LiDAR scans
      format          str        airfisheye  how root is laid out: airfisheye | woodscape | ... (data.format of training)
      format_options  dict|null  null        that format's options, e.g. format_options={views:[FV]}
      deep            bool       false       also decode every image and array (slower)
      limit           int        20          problems listed in the summary
      lidar           str|null   null        LiDAR scans: the sensor (a preset such as hdl64e, or a spec file) to estimate rings
      min_range       float      1.0         LiDAR scans: returns closer than this (m) count as self-hits
      coverage        bool       true        a dataset with LiDAR: also measure the completion input's coverage per ring
      size            int|null   null        coverage: the served image size (null: data.camera.size's default)
      every           int|null   null        coverage: every n-th test frame (null: a few frames spread over the split)
    <BLANKLINE>
    Booleans: true/false, yes/no, on/off, 1/0. Lists: key=[a,b].
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import sys
from collections.abc import Sequence
from concurrent.futures import BrokenExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.cli.options import Command, Parsed, option, parse, render_help, wants_help
from airfisheye_bench.errors import ConfigError, debug_requested, report_user_errors


def _run(command: Command, argv: Sequence[str] | None) -> Parsed | None:
    """The parsed arguments, or ``None`` after printing ``--help``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if wants_help(argv):
        print(render_help(command))
        return None
    return parse(command, argv)


# ------------------------------------------------------------------------------------------------ inspect
@dataclass
class InspectOptions:
    root: str = option("the dataset root folder (it holds dataset.yaml), or a folder / file of LiDAR scans")
    format: str = option("how root is laid out: airfisheye | woodscape | ... (data.format of training)")
    format_options: Any = option("that format's options, e.g. format_options={views:[FV]}", "dict|null")
    deep: bool = option("also decode every image and array (slower)")
    limit: int = option("problems listed in the summary")
    lidar: str | None = option(
        "LiDAR scans: the sensor (a preset such as hdl64e, or a spec file) to estimate rings"
    )
    min_range: float = option("LiDAR scans: returns closer than this (m) count as self-hits")
    coverage: bool = option("a dataset with LiDAR: also measure the completion input's coverage per ring")
    size: int | None = option("coverage: the served image size (null: data.camera.size's default)")
    every: int | None = option("coverage: every n-th test frame (null: a few frames spread over the split)")


INSPECT = Command(
    "inspect",
    InspectOptions,
    "Report missing or malformed files of a dataset, or the rings and removed returns of LiDAR scan files "
    "(exit status 1 when there are problems).",
    "airfisheye-inspect root=DIR",
)


@report_user_errors
def inspect(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-inspect root=DIR [format=woodscape] [deep=true] [limit=20] [coverage=true] [size=128]
    [every=N]``; exit status 1 when problems are found.

    A sound dataset with LiDAR also gets the sparse LiDAR coverage of its completion input per incidence-angle
    ring (``datamodules.coverage``): served at ``size`` with every return and at the paper's density, beside the
    paper sensor at 1536^2, over a few test frames.
    """
    parsed = _run(INSPECT, argv)
    if parsed is None:
        return 0

    from airfisheye_bench.dataset_tools.inspect import inspect_dataset  # deferred: module docstring
    from airfisheye_bench.dataset_tools.inspect_scans import inspect_scans  # deferred: module docstring
    from airfisheye_bench.io.errors import DatasetFormatError  # at run time: see the module docstring

    opts = parsed.options
    for key in ("size", "every"):  # answered before the scan, which may take minutes
        if opts[key] is not None and opts[key] < 1:
            raise ConfigError(f"{key}={opts[key]}: expected a whole number >= 1 (or null)")
    root = Path(opts.root)
    dataset = False  # a dataset in the AirFisheye layout (its coverage can be measured)
    if opts.format != "airfisheye":
        from airfisheye_bench.dataset_tools.inspect_source import inspect_source  # deferred: module docstring

        options = opts.format_options
        options = OmegaConf.to_container(options) if OmegaConf.is_config(options) else options
        if options is not None and not isinstance(options, dict):
            raise ConfigError(
                f"format_options={options!r}: expected a mapping, e.g. format_options={{views:[FV]}}"
            )
        report = inspect_source(root, opts.format, options, deep=opts.deep)
    elif (root / "dataset.yaml").is_file() or not root.exists():
        report = inspect_dataset(opts.root, deep=opts.deep)
        dataset = True
    else:  # a folder (or a file) of LiDAR scans
        try:
            report = inspect_scans(root, opts.lidar, opts.min_range)
        except ValueError as err:
            raise ConfigError(f"lidar={opts.lidar!r}: {err}") from None
        if root.is_file() and report.problems:  # the one file asked about is unusable: a user error
            raise DatasetFormatError(*report.problems[0])
    print(report.summary(limit=opts.limit))
    if dataset and report.ok and opts.coverage:
        _print_coverage(root, opts.size, opts.every)
    return 0 if report.ok else 1


def _print_coverage(root: Path, size: int | None, every: int | None) -> None:
    """The completion input's coverage of a sound dataset (nothing for one without LiDAR)."""
    if size is None:  # the size training serves by default: the data group train.yaml starts from
        from airfisheye_bench.constants import config_dir  # at run time: see the module docstring

        size = int(OmegaConf.load(config_dir() / "data" / "synthetic.yaml").camera.size)
    from datamodules.coverage import dataset_coverage, format_coverage  # torch: only when measured

    coverage = dataset_coverage(root, size, every)
    if coverage is not None:
        print(format_coverage(coverage))


# ---------------------------------------------------------------------------------------------- transcode
@dataclass
class TranscodeOptions:
    src: str = option("the dataset root to read")
    dst: str = option("the new dataset root (must not exist)")
    rgb: str = option("RGB encoding: jpg | png")
    depth: str = option("depth encoding: npy | png16 | pfm")
    jpeg_quality: int = option("JPEG quality, 1..100")
    workers: int = option("worker processes")
    link: bool = option("hard-link files that keep their encoding (copy where linking fails)")


TRANSCODE = Command(
    "transcode",
    TranscodeOptions,
    "Copy a dataset with its RGB and depth files in other encodings (the manifest is rewritten).",
    "airfisheye-transcode src=DIR dst=DIR",
)


@report_user_errors
def transcode(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-transcode src=DIR dst=DIR [rgb=jpg] [depth=npy] [...]``; exit status 2 on an error."""
    parsed = _run(TRANSCODE, argv)
    if parsed is None:
        return 0

    from airfisheye_bench.dataset_tools.transcode import transcode_dataset  # deferred: module docstring
    from airfisheye_bench.io.errors import DatasetFormatError  # at run time: see the module docstring

    try:
        report = transcode_dataset(**parsed.options)
    except (DatasetFormatError, ValueError, OSError, BrokenExecutor) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(report.summary())
    return 0


# -------------------------------------------------------------------------------------------- leaderboard
@dataclass
class LeaderboardOptions:
    runs: Any = option("a folder or a results.json file, or a list of them: [a,b]", "str|list[str]")
    out: str = option("folder of leaderboard.md and leaderboard.csv")
    paper: bool = option("rank next to the paper's baselines")
    skip_invalid: bool = option("leave invalid results.json out (listed in the outputs) instead of failing")
    html: str | None = option("also write a self-contained HTML page to this .html file")
    include_debug: bool = option("also rank smoke runs (trainer=debug: a batch or two; left out by default)")


LEADERBOARD = Command(
    "leaderboard",
    LeaderboardOptions,
    "Rank every results.json by task next to the paper's baselines.",
    "airfisheye-leaderboard runs=DIR|[DIR,FILE,...]",
)


@report_user_errors
def leaderboard(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-leaderboard runs=DIR|[DIR,...] [out=leaderboard] [paper=true] [skip_invalid=false] [html=FILE]
    [include_debug=false]``.

    Runs trained with ``trainer=debug`` (the install check's, the tests') are left out, with a note on stderr,
    unless ``include_debug=true``, which ranks them marked ``[trainer=debug]``.

    Returns:
        0 on success, 1 for missing paths, no results or invalid files.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "runs" / "a" / "results.json", "seg", "test", {"mIoU": 0.3})
        >>> leaderboard([f"runs={root / 'runs'}", f"out={root / 'board'}"])  # doctest: +ELLIPSIS
        # AirFisheye-bench leaderboard
        ...
        0
        >>> sorted(p.name for p in (root / "board").iterdir())
        ['leaderboard.csv', 'leaderboard.md']
    """
    parsed = _run(LEADERBOARD, argv)
    if parsed is None:
        return 0

    from airfisheye_bench.evaluation.leaderboard import (  # at run time: see the module docstring
        LeaderboardError,
        build_leaderboard,
        find_results,
        load_entries,
    )

    opts = parsed.options
    runs = [opts.runs] if isinstance(opts.runs, str) else opts.runs
    if not isinstance(runs, Sequence) or not runs or not all(isinstance(r, str) and r.strip() for r in runs):
        raise ConfigError(f"runs={opts.runs}: expected a folder or results.json, or a list of them [a,b]")
    if opts.html is not None and not opts.html.endswith((".html", ".htm")):
        raise ConfigError(f"html={opts.html}: expected an .html file name")
    # Absolute: the outputs show every path relative to the folder the results were collected from.
    paths = [Path(r.strip()).expanduser().resolve() for r in runs]
    try:
        entries, problems = load_entries(find_results(paths))
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    if problems and not opts.skip_invalid:
        print(f"error: {LeaderboardError(problems)}\n(skip_invalid=true leaves them out)", file=sys.stderr)
        return 1
    for problem in problems:
        print(f"warning: skipped invalid results.json: {problem}", file=sys.stderr)
    debug = sum(e.debug for e in entries)
    if debug and not opts.include_debug:
        entries = [e for e in entries if not e.debug]
        print(
            f"note: left out {debug} row(s) of runs trained with trainer=debug (a batch or two: no result to "
            "rank); include_debug=true ranks them",
            file=sys.stderr,
        )
    if not entries:
        print("error: no valid results.json to rank", file=sys.stderr)
        return 1
    root = os.path.commonpath([p if p.is_dir() else p.parent for p in paths])
    board = build_leaderboard(entries, paper=opts.paper, invalid=problems, root=root)
    written = list(board.write(opts.out))
    if opts.html is not None:
        from airfisheye_bench.evaluation.leaderboard.html import write_html  # matplotlib, only for html=

        written.append(write_html(board, opts.html))
    print(board.to_markdown(), end="")
    print(f"wrote {', '.join(map(str, written))}", file=sys.stderr)
    return 0


# ------------------------------------------------------------------------------------------------- export
@dataclass
class ExportOptions:
    ckpt_path: str = option("a checkpoint, or a run directory (its best checkpoint)")
    out: str = option("the ONNX file to write")
    dynamic_spatial: bool = option("export with dynamic height and width (else fixed at the run's size)")
    batch: int = option("batch size of the example input (>= 2; the batch dimension is dynamic)")
    parity_samples: int = option("validation frames of the ONNX Runtime vs PyTorch parity check")
    quantize: str = option("also write <out stem>.int8.onnx: none | dynamic | static")
    opset: int = option("ONNX opset")
    calib_samples: int = option("validation frames calibrating static quantisation")
    eval_samples: int = option("validation frames scoring the int8 model (0: the whole split)")
    repeats: int = option("timed runs of the latency comparison")
    bake_camera: bool = option(
        "a camera-aware model (model.camera_input=rays): store the data's camera's ray map in the file, which then "
        "takes the image alone (else rays is a second input)"
    )
    report_json: str | None = option(
        "also write the report (parity, latency, int8 metrics) as JSON to this file"
    )
    mlflow_run: str | None = option(
        "log the ONNX file(s) and parity numbers to an MLflow run: auto (the checkpoint's run) or a run id"
    )
    mlflow_tracking_uri: str | None = option(
        "with a run id: its store or server (null: the run's recorded one)"
    )


EXPORT = Command(
    "export",
    ExportOptions,
    "Export a trained run to one verified, self-describing ONNX file (optionally also int8).",
    "airfisheye-export ckpt_path=<ckpt or run dir> out=model.onnx",
    extra=lambda key: key.startswith("data."),
    extra_help="data.<key>=<value>: changes to the run's data config (e.g. data.camera.size=256)",
)


@report_user_errors
def export(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-export ckpt_path=<ckpt or run dir> out=model.onnx [...]`` (:func:`export_deployment`).

    Returns:
        0 success, 1 export or parity failure (nothing written at ``out``), 2 bad arguments or inputs (checkpoint,
        run config, overrides), 3 the fp32 model was exported and verified but the int8 quantisation failed.
    """
    parsed = _run(EXPORT, argv)
    if parsed is None:
        return 0

    from airfisheye_bench.export.deploy import (  # at run time: see the module docstring
        ExportError,
        export_deployment,
        log_export,
    )
    from airfisheye_bench.export.onnx import OnnxParityError  # at run time: see the module docstring

    # Progress of this command only (export.deploy, export.quantize): the exporter and the quantiser log pages of
    # INFO lines.
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    logging.getLogger("airfisheye_bench.export").setLevel(logging.INFO)
    kwargs = dict(parsed.options)
    mlflow_run, mlflow_uri = kwargs.pop("mlflow_run"), kwargs.pop("mlflow_tracking_uri")
    report_json = kwargs.pop("report_json")
    if mlflow_run:
        from omegaconf import OmegaConf  # with the checks below: nothing is imported for --help

        from airfisheye_bench.config_checks import check_extras  # before the minutes of exporting

        check_extras(OmegaConf.create({"mlflow_run": mlflow_run}))
    data_overrides = {key.removeprefix("data."): value for key, value in parsed.extra.items()}
    try:
        report = export_deployment(**kwargs, data_overrides=data_overrides or None)
    except OnnxParityError as err:
        print(f"error: parity check failed, {kwargs['out']} was not written: {err}", file=sys.stderr)
        return 1
    except ExportError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except (FileNotFoundError, ValueError) as err:
        if debug_requested():
            raise
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(report.summary())
    if report_json:
        record = report.to_dict()
        record["provenance"] = _export_provenance(argv, report.checkpoint)
        atomic_write_text(report_json, json.dumps(record, indent=2) + "\n")
        print(f"wrote {report_json}")
    if mlflow_run:
        log_export(report, mlflow_run, mlflow_uri)
    if report.quantization is not None and not report.quantization.ok:
        return 3
    return 0


def _export_provenance(argv: Sequence[str] | None, checkpoint: Path) -> dict[str, Any]:
    """Where an export report comes from: the export's commit and command, and how its checkpoint was trained
    (``trained``: the run's ``benchmark.json`` of ``scripts/quickstart_benchmark.py`` or ``provenance.json`` of
    ``scripts/occlusion_ablation.py``, when the run has one; ``null`` when it does not, which a report citing it
    must then say)."""
    # Deferred: only an export that writes a report needs git's answer and the run's records.
    from airfisheye_bench.runs import run_directory  # deferred with it
    from airfisheye_bench.studies.provenance import provenance  # deferred with it

    record = provenance("scripts/export_onnx.py", argv)
    run = run_directory(checkpoint)
    trained = None
    for name in ("benchmark.json", "provenance.json"):
        if run is not None and (run / name).is_file():
            trained = {"record": name, **json.loads((run / name).read_text(encoding="utf-8"))}
            break
    record["trained"] = trained
    return record


# ------------------------------------------------------------------------------------------------ predict
@dataclass
class PredictOptions:
    ckpt_path: str = option("the model: a run directory, a .ckpt file or an .onnx file of airfisheye-export")
    input: str = option("the footage: a folder of images or a video file (the video extra)")
    out: str | None = option("the folder to write, must not exist (null: predictions/<input name>)")
    input_format: str = option("fisheye (frames of the model's lens) | erp (equirectangular panoramas)")
    camera: str | None = option("the footage's lens: a calibration file (null: the model's lens at its size)")
    camera_name: str | None = option("which camera of a calibration file that holds several")
    allow_camera_mismatch: bool = option(
        "predict frames of another size or lens anyway, resized to the model's"
    )
    erp_yaw_deg: float = option("input_format=erp: the view turned left of the panorama's centre (degrees)")
    erp_pitch_deg: float = option("input_format=erp: the view tilted down (degrees)")
    sparse: str | None = option("completion: folder of <frame>.npy (m) or 16-bit <frame>.png (m * 256) maps")
    depth_format: str = option("depth and completion: png16 (round(m * 256)) | npy (float32 metres)")
    batch_size: int = option("frames per model call")
    device: str = option("checkpoint inference: auto (cuda if available) | cpu | cuda")
    threads: int | None = option("ONNX Runtime intra-op threads (null: its default)")
    tta: str | None = option("test-time augmentation: null | flip")
    progress: bool = option("show a progress bar (log lines when not in a terminal)")
    views: Any = option(
        "a perspective model on fisheye frames: cube | [[yaw,pitch],...] (the footage's lens from camera=)",
        "str|list|null",
    )
    view_depth: str = option(
        "with views: what the model's depth measures: range (this project's) | z (its axis)"
    )


PREDICT = Command(
    "predict",
    PredictOptions,
    "Run a trained model on your own footage: label or depth maps, colourised, and input | prediction previews.",
    "airfisheye-predict ckpt_path=<run dir, .ckpt or .onnx> input=<folder or video>",
)


@report_user_errors
def predict(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-predict ckpt_path=<run dir | .ckpt | .onnx> input=<folder | video> [out=DIR] [...]``
    (:func:`~airfisheye_bench.prediction.predict.predict_footage`); exit status 2 on a user error, nothing written.
    """
    parsed = _run(PREDICT, argv)
    if parsed is None:
        return 0

    from airfisheye_bench.prediction.predict import predict_footage  # at run time: see the module docstring

    # This command's warnings and progress lines; the libraries' INFO lines are not the user's business here.
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    logging.getLogger("airfisheye_bench.prediction.predict").setLevel(logging.INFO)
    report = predict_footage(**parsed.options)
    print(report.summary())
    return 0


# ---------------------------------------------------------------------------------------------- generate
@dataclass
class GenerateOptions:
    preset: str = option("the preset to generate (airfisheye-generate presets lists them)")
    out: str | None = option("the dataset folder to write (null: the cache, unmodified presets only)")
    seed: int = option("random seed of the scenes and flights")
    workers: int | None = option("worker processes (null: 1 with out=, automatic for the cache)")
    device: str = option("torch device of the renderer")
    verify: bool = option("check the written dataset against its manifest.json")
    contact_sheet: bool = option(
        "also write a contact sheet PNG inside the dataset folder (contact_sheet.png)"
    )
    progress: bool = option("show progress bars")
    shards: int = option("split the work into this many shards of whole trajectories (with shard=)")
    shard: Any = option(
        "write only this shard, 0 .. shards-1, into out= (the last to finish merges), or merge: finish the "
        "dataset of shards all written",
        "int|merge|null",
    )


@dataclass
class VerifyOptions:
    root: str = option("the dataset root to check against its manifest.json")


@dataclass
class ContactSheetOptions:
    root: str = option("the dataset root")
    sample: str | None = option("the frame to show, env/traj/frame (null: the first)")
    png: str | None = option("the PNG to write (null: <root>/contact_sheet.png)")


@dataclass
class BenchOptions:
    presets: list[str] = option("presets to time")
    frames: int = option("frames timed per preset (after one warm-up frame)")
    device: str = option("torch device of the renderer")


def _synth_key(key: str) -> bool:
    from airfisheye_bench.synth.presets import SynthConfig  # at run time: see the module docstring

    return (
        key.startswith(("flight.", "camera."))
        or key == "lidar.preset"
        or key in {f.name for f in dataclasses.fields(SynthConfig)}
    )


GENERATE = Command(
    "generate",
    GenerateOptions,
    "Generate a synthetic AirFisheye dataset (subcommands: verify, contact_sheet, presets, bench; each has --help).",
    "airfisheye-generate [preset=tiny] [out=DIR]",
    extra=_synth_key,
    extra_help="<field>=<value>, flight.<field>=<value>: a field of the preset's SynthConfig / FlightConfig; "
    "camera.calibration=<file> [camera.camera=<name>] [camera.size=N] [camera.fit=pad|crop]: a calibrated lens "
    "(formats: OpenCV, ROS, Kalibr, basalt, COLMAP, camodocal / KITTI-360, WoodScape, OCamCalib; docs/design.md, "
    "Calibration files)",
)
GENERATE_SUBCOMMANDS = {
    "verify": Command(
        "generate_verify",
        VerifyOptions,
        "Check a dataset against its manifest.json (exit status 1 on a mismatch).",
        "airfisheye-generate verify root=DIR",
    ),
    "contact_sheet": Command(
        "generate_contact_sheet",
        ContactSheetOptions,
        "Write a contact sheet PNG of one frame (every modality).",
        "airfisheye-generate contact_sheet root=DIR",
    ),
    "bench": Command(
        "generate_bench",
        BenchOptions,
        "Time the full frame writer of presets (a markdown table).",
        "airfisheye-generate bench",
    ),
}


@report_user_errors
def generate(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-generate [verify|contact_sheet|presets|bench] [key=value ...]``; 1 when verification fails.

    ``airfisheye-generate preset=tiny out=DIR face_size=96 flight.altitude_m=[5,30]`` generates a modified
    preset (any :class:`~airfisheye_bench.synth.presets.SynthConfig` field, ``flight.<field>`` for its
    :class:`~airfisheye_bench.synth.trajectory.FlightConfig`).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    name = argv.pop(0) if argv and "=" not in argv[0] and argv[0] not in ("-h", "--help") else "generate"
    if name == "presets":
        if wants_help(argv):
            print("List the presets: frames, trajectories, image sizes, LiDAR pattern.")
            print("\nusage: airfisheye-generate presets")
            return 0
        if argv:
            raise ConfigError(f"airfisheye-generate presets takes no arguments, got {argv}")
        from airfisheye_bench.synth.cli import presets_table  # at run time: see the module docstring

        print(presets_table())
        return 0
    if name != "generate" and name not in GENERATE_SUBCOMMANDS:
        raise ConfigError(
            f"unknown subcommand {name!r} of airfisheye-generate; expected key=value options or one of "
            f"{['presets', *GENERATE_SUBCOMMANDS]}"
        )
    parsed = _run(GENERATE_SUBCOMMANDS.get(name, GENERATE), argv)
    if parsed is None:
        return 0

    from airfisheye_bench.synth import cli as synth  # at run time: see the module docstring

    opts = parsed.options
    if name == "verify":
        return synth.verify_dataset(Path(opts.root))
    if name == "contact_sheet":
        return synth.write_sheet(Path(opts.root), opts.sample, opts.png)
    if name == "bench":
        timings = {p: synth.bench_frame_writer(p, opts.frames, opts.device) for p in opts.presets}
        print(synth.bench_markdown(timings))
        return 0
    return synth.generate(
        opts.preset,
        parsed.extra,
        None if opts.out is None else Path(opts.out),
        seed=opts.seed,
        workers=opts.workers,
        device=opts.device,
        verify=opts.verify,
        contact_sheet=opts.contact_sheet,
        progress=opts.progress,
        shards=opts.shards,
        shard=opts.shard,
    )
