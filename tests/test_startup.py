"""The start-up of the ``pedmesh`` command (issue 46): parsing a command line imports
neither the models nor numba, the help still names what they know, and the program frees
the interpreter's shutdown from its objects."""

from __future__ import annotations

import gc
import subprocess
import sys

import pytest

from pedmesh.cli import main

HEAVY = ("numba", "pedmesh.models", "pedmesh.run", "scipy")


def _fresh(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


def test_parsing_a_run_command_line_imports_no_model_and_no_numba():
    out = _fresh(
        "import sys\n"
        "import pedmesh.cli\n"
        "from pedmesh.cli._main import build_parser\n"
        "args = build_parser('run').parse_args(['run', 'room.json', '--model', 'eos',\n"
        "                                       '--t-end', '0.1', '-q'])\n"
        "assert args.model == 'eos' and args.t_end == 0.1 and args.quiet\n"
        f"print([m for m in {HEAVY!r} if m in sys.modules])\n"
        "build_parser()  # every command\n"
        "print([m for m in ('numba', 'pedmesh.models') if m in sys.modules])\n"
        "print(sorted(m for m in sys.modules if m.startswith('pedmesh.cli.cmd_')))\n")
    run_only, every, commands = out.splitlines()
    assert run_only == "[]"
    assert every == "[]"
    assert "pedmesh.cli.cmd_report" in commands


def test_a_command_line_imports_its_own_command_only():
    out = _fresh(
        "import sys\n"
        "from pedmesh.cli._main import SUBCOMMANDS, build_parser\n"
        "build_parser('run')\n"
        "print(sorted(m for m in sys.modules if m.startswith('pedmesh.cli.cmd_')))\n")
    # (run's module imports the mesh and preset options it shares)
    assert out == str(["pedmesh.cli.cmd_mesh", "pedmesh.cli.cmd_presets",
                       "pedmesh.cli.cmd_run"])


def test_run_help_still_names_the_models_the_output_files_and_the_limits(capsys):
    from pedmesh.models import model_names
    from pedmesh.run.driver import MAX_PEOPLE, MAX_STEPS
    from pedmesh.run.output import OUTPUT_FILES

    with pytest.raises(SystemExit) as info:
        main(["run", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    assert "available: " + ", ".join(model_names()) in " ".join(text.split())
    for name in OUTPUT_FILES:
        assert name in text
    assert f"{MAX_PEOPLE:,}" in text and f"{MAX_STEPS:,}" in text
    for command in ("compare", "ensemble"):  # (they share run's --max-people)
        with pytest.raises(SystemExit):
            main([command, "--help"])
        assert f"{MAX_PEOPLE:,}" in capsys.readouterr().out


def test_every_command_is_listed_and_an_unknown_one_refused(capsys):
    from pedmesh.cli._main import SUBCOMMANDS

    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    for name in SUBCOMMANDS:
        assert name in text
    with pytest.raises(SystemExit) as info:
        main(["rnu", "room.json"])
    assert info.value.code == 2
    assert "invalid choice: 'rnu'" in capsys.readouterr().err


def test_main_with_a_command_line_leaves_the_collector_alone(capsys):
    before = gc.get_freeze_count(), gc.get_threshold()
    assert main(["presets"]) == 0
    assert (gc.get_freeze_count(), gc.get_threshold()) == before
    capsys.readouterr()


def test_the_program_collects_rarely_and_freezes_its_objects_before_exit():
    """``main()`` as the program (the command line from sys.argv) runs full collections
    less often, and moves the objects alive at its end out of the collections of the
    interpreter's shutdown."""
    from pedmesh.cli._main import FULL_COLLECTION_EVERY

    r = subprocess.run([sys.executable, "-c",
                        "import gc, sys\n"
                        "from pedmesh.cli import main\n"
                        "sys.argv = ['pedmesh', 'presets']\n"
                        "before = gc.get_freeze_count(), gc.get_threshold()\n"
                        "rc = main()\n"
                        "print(rc, before, gc.get_freeze_count() > 0, gc.get_threshold(),\n"
                        "      file=sys.stderr)\n"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0
    g0, g1, g2 = gc.get_threshold()  # (this process's, as Python sets them)
    assert r.stderr.strip() == (f"0 (0, {(g0, g1, g2)}) True "
                                f"{(g0, g1, max(g2, FULL_COLLECTION_EVERY))}")


def test_a_model_asked_for_by_name_imports_its_own_module_only():
    out = _fresh(
        "import sys\n"
        "from pedmesh.models import get_model\n"
        "assert get_model('eos').name == 'eos'\n"
        "print(sorted(m for m in sys.modules if m.startswith('pedmesh.models.')))\n"
        "from pedmesh.models import model_names\n"
        "print(model_names())\n")
    first, names = out.splitlines()
    assert "'pedmesh.models.continuum.eos'" in first
    for other in ("pedmesh.models.sfm", "continuum.derived", "continuum.rdue",
                  "continuum.pw'"):
        assert other not in first
    for name in ("sfm", "eos", "rdue", "pw", "mac1"):  # (every built-in, when listed)
        assert f"'{name}'" in names


def test_a_built_in_name_is_taken_before_the_built_ins_are_loaded():
    out = _fresh(
        "from pedmesh.models import ModelEntry, get_model, register_model\n"
        "for name in ('eos', 'sf', 'hughes'):\n"
        "    try:\n"
        "        register_model(ModelEntry(name=name, build=print))\n"
        "    except ValueError as exc:\n"
        "        print(exc)\n"
        "print(get_model('sf').name, get_model('hughes').name)\n")
    assert out.splitlines() == ["a model named 'eos' is already registered",
                                "a model named 'sf' is already registered",
                                "a model named 'hughes' is already registered",
                                "sfm rdue"]


def test_a_built_in_model_module_imported_first_registers_every_model():
    out = _fresh(
        "from pedmesh.models.continuum.eos import EquationOfStateModel\n"
        "from pedmesh.models import get_model, model_names\n"
        "print(get_model('eos').physics is EquationOfStateModel, 'sfm' in model_names())\n")
    assert out == "True True"


def test_an_eos_run_imports_no_other_model(geometries_dir, tmp_path):
    out = _fresh(
        "import sys\n"
        "from pedmesh.cli._main import _main\n"
        f"rc = _main(['run', {str(geometries_dir / 'example2.json')!r}, '--model', 'eos',\n"
        f"            '--t-end', '0.1', '--out', {str(tmp_path / 'run')!r}, '-q'], False)\n"
        "assert rc == 0\n"
        "print(sorted(m for m in sys.modules if m.startswith('pedmesh.models.sfm')\n"
        "             or m.endswith(('.derived', '.rdue', '.pw'))))\n")
    assert out.splitlines()[-1] == "[]"
