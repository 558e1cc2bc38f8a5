"""Parameter presets (pedmesh.presets): values, precedence, room files, the CLI."""

from __future__ import annotations

import json
from dataclasses import fields

import pytest

from pedmesh.cli import main
from pedmesh.errors import ParameterError
from pedmesh.presets import DEFAULT_PRESET, PRESETS, get_preset, preset_overrides

TABLE1 = {"m": 60.0, "tau": 0.5, "beta": 0.05, "U_f": 1.034, "R": 0.7, "A": 2000.0,
          "B": 0.08, "r": 0.15, "k": 1.2e5, "kappa": 2.4e5, "speed_law": "exponential"}


def test_paper_is_table_1_and_the_model_defaults():
    from pedmesh.models.sfm.params import SocialForceParams

    assert get_preset("paper").overrides() == TABLE1
    defaults = SocialForceParams()
    for k, v in TABLE1.items():
        assert getattr(defaults, k) == v
    assert {f.name for f in fields(SocialForceParams)} >= set(TABLE1)


def test_every_value_has_a_unit_and_a_source():
    for pre in PRESETS.values():
        for k, v in pre.values.items():
            assert v.source, (pre.name, k)
            assert isinstance(v.value, str) or v.unit, (pre.name, k)


def test_a_preset_sets_only_what_a_model_has_and_overrides_win():
    from pedmesh.models import get_model

    def mp(name):
        return get_model(name).parameter_names

    p = preset_overrides("weidmann", mp("rdue"), {"U_f": 1.2})
    assert p == {"speed_law": "weidmann", "U_f": 1.2, "rho_jam": 5.4, "gamma_w": 1.913}
    sfm = preset_overrides("weidmann", mp("sfm"))
    assert sfm["r"] == 0.15 and sfm["R"] == 0.7 and sfm["speed_law"] == "weidmann"
    assert "R" not in preset_overrides("paper", mp("eos"))  # (the SFM's kernel width)


def test_bad_preset_name():
    with pytest.raises(ParameterError, match="unknown preset 'fast' \\(presets: paper"):
        get_preset("fast")


def _room_file(tmp_path, geometries_dir, preset):
    data = json.loads((geometries_dir / "l_shaped.json").read_text())
    if preset is not None:
        data["preset"] = preset
    path = tmp_path / "room.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("room_preset, cli, used", [
    (None, None, DEFAULT_PRESET), ("weidmann", None, "weidmann"),
    ("weidmann", "paper", "paper"), (None, "weidmann", "weidmann")])
def test_which_preset_a_run_uses(tmp_path, geometries_dir, room_preset, cli, used):
    room = _room_file(tmp_path, geometries_dir, room_preset)
    out = tmp_path / "run"
    args = ["run", str(room), "--model", "rdue", "--out", str(out), "-q", "--t-end", "1",
            "--max-area", "2"]
    if cli:
        args += ["--preset", cli]
    assert main(args + ["--param", "U_f=1.1"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["settings"]["preset"] == used
    assert s["settings"]["overrides"] == {"U_f": 1.1}
    p = s["parameters"]
    assert p["U_f"] == 1.1  # the override beats the preset
    assert p["speed_law"] == get_preset(used).values["speed_law"].value


def test_bad_preset_in_room_file_or_command_is_one_line(tmp_path, geometries_dir, capsys):
    room = _room_file(tmp_path, geometries_dir, "fastest")
    assert main(["run", str(room), "--model", "rdue", "-q", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown preset 'fastest'" in err[0] and "room.json" in err[0]
    good = _room_file(tmp_path, geometries_dir, None)
    assert main(["run", str(good), "--model", "rdue", "-q", "--preset", "x",
                 "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"pedmesh: error: unknown preset 'x' (presets: {', '.join(PRESETS)})"]


def test_room_file_round_trip_keeps_the_preset(tmp_path, geometries_dir):
    from pedmesh.io import load_room, save_room

    room = load_room(_room_file(tmp_path, geometries_dir, "weidmann"))
    assert room.preset == "weidmann"
    assert load_room(save_room(room, tmp_path / "again.json")).preset == "weidmann"


def test_the_papers_examples_name_the_paper_preset(load_shipped):
    for i in (1, 2, 3):
        assert load_shipped(f"example{i}.json").preset == "paper"


def test_presets_command_lists_values_units_sources(capsys):
    assert main(["presets"]) == 0
    out = capsys.readouterr().out
    for name in PRESETS:
        assert out.count(f"{name}") >= 1
    assert "U_f              1.034 m/s       paper, Table 1" in out
    assert "rho_jam                   5.4 ped/m^2   Weidmann" in out
    assert main(["presets", "nope"]) == 2


def test_calibrate_takes_a_preset(tmp_path, monkeypatch):
    """`pedmesh calibrate --preset` builds the SFM parameters of the preset (with --param
    on top); checked on the parameters handed to the calibration, not by running it."""
    import pedmesh.calibration as cal

    seen = {}

    def fake(params, options, progress, on_row):
        seen["params"] = params
        raise KeyboardInterrupt

    monkeypatch.setattr(cal, "calibrate", fake)
    rc = main(["calibrate", "--preset", "weidmann", "--param", "A=1500", "-q",
               "-o", str(tmp_path / "e.json")])
    assert rc == 130
    assert seen["params"].A == 1500 and seen["params"].r == 0.15


def test_validated_is_the_fit_and_the_default():
    """The validated preset is the fit's record (pedmesh/data/validated.json), the default,
    and its eos calibration was measured with its social force parameters."""
    from pedmesh.presets import DATA

    fit = json.loads((DATA / "validated.json").read_text())
    pre = get_preset("validated")
    assert DEFAULT_PRESET == "validated"
    for k, v in fit["parameters"].items():
        if k != "preset":  # (the preset the fit started from)
            assert pre.values[k].value == v
    for k in fit["fitted"]:
        assert pre.values[k].source.startswith("fitted")
    for k in fit.get("carried", {}):  # (fixed at an earlier fit's values)
        assert pre.values[k].value == fit["carried"][k]
        assert pre.values[k].source.startswith("fitted")
        if k != "speed_table":
            assert pre.values[k].source.startswith("fitted with Weidmann's law")
    assert pre.values["speed_law"].value == "table" and pre.values["U_f"].value == 1.34
    assert pre.values["density_self"].value == 0
    # the SFM's table is in its kernel density; the continuum models get its measured
    # fundamental diagram instead (tests/calibration/test_fundamental_diagram.py)
    fd = json.loads((DATA / "fd_validated.json").read_text())
    assert pre.continuum["speed_table"].value == fd["speed_table"] != fit["parameters"][
        "speed_table"]
    assert "rho_shift" not in pre.values
    cal = json.loads((DATA / "eos_validated.json").read_text())
    assert pre.values["calibration"].value == str(DATA / "eos_validated.json")
    assert cal["status"] == "complete"
    for k, v in cal["parameters"].items():
        if k in pre.values:
            assert v == pytest.approx(pre.values[k].value), k


def test_continuum_values_reach_only_the_continuum_models(monkeypatch):
    """A preset's continuum values (e.g. the continuum models' own speed table) replace
    its values for every model but the SFM, and --param overrides still win."""
    from pedmesh import presets
    from pedmesh.presets import Preset, Value
    from pedmesh.models import get_model

    def mp(name):
        return get_model(name).parameter_names

    pre = Preset("two", "test", {"speed_law": Value("table", "", "s"),
                                 "speed_table": Value("0:1 1:0.5", "", "sfm's"),
                                 "r": Value(0.2, "m", "s")},
                 {"speed_table": Value("0:1 2:0.5", "", "continuum's")})
    monkeypatch.setitem(presets.PRESETS, "two", pre)
    sfm = preset_overrides("two", mp("sfm"), continuum=False)
    assert sfm["speed_table"] == "0:1 1:0.5" and sfm["r"] == 0.2
    for model in ("eos", "rdue", "pw", "mac1"):
        p = preset_overrides("two", mp(model), continuum=model != "sfm")
        assert p["speed_table"] == "0:1 2:0.5" and p["speed_law"] == "table"
        assert ("r" in p) == (model in ("eos", "mac1"))  # (those two derive from the SFM)
    assert preset_overrides("two", mp("eos"), {"speed_table": "0:1 3:0"},
                            continuum=True)["speed_table"] == "0:1 3:0"
    assert pre.overrides()["speed_table"] == "0:1 1:0.5"  # (without a model: the values)


def test_presets_lists_a_models_declared_parameters(capsys):
    """`pedmesh presets --model NAME` prints what --param may set, from the declarations."""
    from pedmesh import parameters as P

    assert main(["presets", "--model", "eos"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("eos (continuum)")
    for name in ("calibration", "cfl", "A", "empty_below"):
        assert f"  {name} " in out
    assert "\n  dt " not in out  # (the social force model's)
    assert f"{P.get('U_f').default:g} m/s" in out
    assert main(["presets", "--model", "nope"]) == 2


def test_a_fingerprint_changes_with_the_values_and_the_files_they_name(tmp_path, monkeypatch):
    import dataclasses

    from pedmesh import presets
    from pedmesh.presets import Value, fingerprint

    prints = {name: fingerprint(name) for name in PRESETS}
    assert len(set(prints.values())) == len(PRESETS)
    assert all(len(p) == 16 and int(p, 16) >= 0 for p in prints.values())
    a, b = tmp_path / "a" / "eos.json", tmp_path / "b" / "eos.json"
    for f in (a, b):
        f.parent.mkdir()
        f.write_text('{"table": [1, 2]}')
    base = PRESETS["weidmann"]

    def with_values(**values):
        p = dataclasses.replace(base, values={**base.values, **{
            k: Value(v, "", "test") for k, v in values.items()}})
        monkeypatch.setitem(presets.PRESETS, "weidmann", p)
        return fingerprint("weidmann")

    same_file = with_values(calibration=str(a))
    assert with_values(calibration=str(b)) == same_file  # (where it is kept: the same)
    b.write_text('{"table": [1, 3]}')
    assert with_values(calibration=str(b)) != same_file  # (what it holds: another)
    assert with_values(U_f=1.3) != with_values(U_f=1.34) == prints["weidmann"]
