"""One command-line system: every command answers ``--help``, reads typed ``key=value`` options, and names the key
of a bad one in one line; booleans mean the same everywhere."""

from __future__ import annotations

import dataclasses
import functools
import os
import subprocess
import sys
import typing
from pathlib import Path

import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

from airfisheye_bench.cli import commands
from airfisheye_bench.cli.options import parse, render_help
from airfisheye_bench.constants import config_dir
from airfisheye_bench.errors import EXIT_USER_ERROR, ConfigError
from tests.helpers.commands import EVALUATE, assert_one_line_error, exit_status, run_in_process

ROOT = Path(__file__).resolve().parents[1]
SMALL = {
    "inspect": (commands.inspect, commands.INSPECT, ["root=/nowhere"]),
    "transcode": (commands.transcode, commands.TRANSCODE, ["src=/a", "dst=/b"]),
    "leaderboard": (commands.leaderboard, commands.LEADERBOARD, ["runs=/nowhere"]),
    "export": (commands.export, commands.EXPORT, ["ckpt_path=/a", "out=/b.onnx"]),
    "predict": (commands.predict, commands.PREDICT, ["ckpt_path=/a", "input=/b"]),
    "generate": (commands.generate, commands.GENERATE, []),
    **{
        f"generate {name}": (commands.generate, sub, ["root=/nowhere"] if name != "bench" else [])
        for name, sub in commands.GENERATE_SUBCOMMANDS.items()
    },
}


def _argv(name: str, args: list[str]) -> list[str]:
    """The subcommand word of ``generate <sub>`` first, then ``args``."""
    return [*name.split()[1:], *args]


@pytest.mark.parametrize("name", sorted(SMALL))
def test_every_config_file_matches_its_schema(name: str) -> None:
    _, command, _ = SMALL[name]
    assert (config_dir() / f"{command.name}.yaml").is_file()
    defaults = parse(command, SMALL[name][2]).options  # composes: every yaml key is a typed schema field
    assert list(defaults) == [f.name for f in dataclasses.fields(command.schema)]


@functools.cache
def _help(name: str) -> str:
    """``render_help`` of a command, once per session (it composes the command's config)."""
    return render_help(SMALL[name][1])


@pytest.mark.parametrize("name", sorted(SMALL))
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_lists_every_option_with_type_and_default(name: str, flag: str, capsys) -> None:
    function, command, _ = SMALL[name]
    assert function(_argv(name, [flag])) == 0
    out = capsys.readouterr().out
    assert out == _help(name) + "\n"
    for field in dataclasses.fields(command.schema):
        (line,) = [line for line in out.splitlines() if line.strip().startswith(f"{field.name} ")]
        assert field.metadata["help"] in line


@pytest.mark.parametrize("name", sorted(SMALL))
def test_unknown_keys_and_bad_types_are_one_line_naming_the_key(name: str, capsys) -> None:
    function, command, required = SMALL[name]
    assert exit_status(function, _argv(name, [*required, "colour=red"])) == EXIT_USER_ERROR
    err = capsys.readouterr().err
    assert err.startswith("error: unknown option 'colour'") and len(err.splitlines()) == 1
    for key in typing.get_type_hints(command.schema):
        if typing.get_type_hints(command.schema)[key] in (bool, int):
            assert exit_status(function, _argv(name, [*required, f"{key}=maybe"])) == EXIT_USER_ERROR
            err = capsys.readouterr().err
            assert err.startswith(f"error: {key}=maybe: expected ") and len(err.splitlines()) == 1


#: The boolean spellings of the help text ("Booleans: true/false, yes/no, on/off, 1/0").
BOOLEANS = {
    "true": True,
    "yes": True,
    "on": True,
    "1": True,
    "false": False,
    "no": False,
    "off": False,
    "0": False,
}


@dataclasses.dataclass
class _OneFlag:
    flag: bool = False


@pytest.mark.parametrize(("text", "value"), BOOLEANS.items())
def test_the_schemas_grammar_reads_every_boolean_spelling(text: str, value: bool) -> None:
    """The spellings, the way a command's compose reads them: Hydra's override parser types the text (a bool, an
    int or a string), then ``OmegaConf.update`` sets it on a structured config's ``bool``."""
    (override,) = OverridesParser.create().parse_overrides([f"flag={text}"])
    cfg = OmegaConf.structured(_OneFlag)
    OmegaConf.update(cfg, "flag", override.value(), merge=True)
    assert cfg.flag is value


def _flags(command) -> list[str]:
    """The options a command's schema types ``bool``."""
    hints = typing.get_type_hints(command.schema)
    return [f.name for f in dataclasses.fields(command.schema) if hints[f.name] is bool]


@pytest.mark.parametrize("name", sorted(n for n in SMALL if _flags(SMALL[n][1])))
def test_booleans_mean_the_same_for_every_command(name: str) -> None:
    """Each command's boolean options are typed ``bool`` by its schema, so they take those spellings: one of each
    value through the command's own parse (a compose each: 12 over the six commands, where every spelling of each of
    their 11 options would be 88)."""
    _, command, required = SMALL[name]
    for text in ("yes", "off"):
        options = parse(command, [*required, *(f"{flag}={text}" for flag in _flags(command))]).options
        assert all(options[flag] is BOOLEANS[text] for flag in _flags(command)), (name, text)


def test_comma_lists_are_refused_with_the_list_spelling() -> None:
    with pytest.raises(ConfigError, match=r"write a list, runs=\[a,b\]"):
        parse(commands.LEADERBOARD, ["runs=a,b"])
    assert parse(commands.LEADERBOARD, ["runs=[a,b]"]).options.runs == ["a", "b"]
    assert parse(commands.GENERATE_SUBCOMMANDS["bench"], ["presets=[tiny]"]).options.presets == ["tiny"]


def test_extra_keys_are_typed_by_the_same_grammar() -> None:
    parsed = parse(commands.EXPORT, ["ckpt_path=r", "out=x.onnx", "data.camera.size=96", "data.root=null"])
    assert parsed.extra == {"data.camera.size": 96, "data.root": None}
    parsed = parse(commands.GENERATE, ["face_size=8", "flight.altitude_m=[5,30]"])
    assert parsed.extra == {"face_size": 8, "flight.altitude_m": [5, 30]}


@pytest.mark.parametrize(
    ("script", "names"),
    [
        ("train.py", ("task", "trainer", "ckpt_path")),
        ("scripts/evaluate.py", ("onnx_path", "split", "\nout: ", "\noutput_dir: ${out}")),
    ],
)
def test_hydra_commands_answer_help(script: str, names: tuple[str, ...]) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, script, "--help"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert all(name in done.stdout for name in names), done.stdout


def test_evaluate_refuses_out_and_its_former_name_output_dir_naming_two_folders(tmp_path: Path) -> None:
    """``airfisheye-evaluate`` takes ``out=`` like the other commands and ``output_dir=`` as before; both at once must
    name one folder. The refusal writes nothing (the run directory Hydra made is taken back)."""
    args = ["ckpt_path=/nowhere.ckpt", f"out={tmp_path / 'a'}", f"output_dir={tmp_path / 'b'}"]
    done = run_in_process(EVALUATE, [*args, f"hydra.run.dir={tmp_path / 'run'}"])
    assert_one_line_error(done, f"out={tmp_path / 'a'}", f"output_dir={tmp_path / 'b'}", "give out= alone")
    assert list(tmp_path.iterdir()) == []


def test_a_script_reports_a_bad_option_without_traceback(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["PYTHONPATH"] = str(ROOT)
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "leaderboard.py"), "runs=x", "paper=maybe"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == EXIT_USER_ERROR and "Traceback" not in done.stderr
    assert done.stderr.splitlines() == [
        "error: paper=maybe: expected a boolean (true/false, yes/no, on/off, 1/0)"
    ]


def test_generate_presets_answers_help_and_takes_no_options(capsys) -> None:
    assert (
        commands.generate(["presets", "--help"]) == 0
        and "usage: airfisheye-generate presets" in capsys.readouterr().out
    )
    assert exit_status(commands.generate, ["presets", "seed=1"]) == EXIT_USER_ERROR
    assert exit_status(commands.generate, ["presetz"]) == EXIT_USER_ERROR
    assert "unknown subcommand 'presetz'" in capsys.readouterr().err


def test_help_and_bad_options_do_not_import_torch() -> None:
    """``--help`` and a mistyped option are answered before the libraries (torch, Lightning) are imported."""
    probe = (
        "import sys\n"
        "from airfisheye_bench.cli import commands\n"
        "for command in (commands.inspect, commands.transcode, commands.leaderboard, commands.export,\n"
        "                commands.predict):\n"
        "    command(['--help'])\n"
        "commands.generate(['verify', '--help'])\n"
        "try:\n"
        "    commands.inspect(['root=/nowhere', 'deep=maybe'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print('torch' in sys.modules)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "False"
