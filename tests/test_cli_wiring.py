"""The command line's wiring to the library: options made from the settings dataclasses, warnings and names
the library gives reaching the user, columns of plot and export, drilling, Dask and process pools."""

from dataclasses import fields

import pytest
from conftest import run

from rodcont.cli import main_group
from rodcont.settings import TraceOptions


def assert_one_line_error(code, out, err, *fragments):
    assert code == 2, (code, out, err)
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("rodcont: error:"), err
    for f in fragments:
        assert f in lines[0], (f, lines[0])


# --------------------------------------------------------------------------
# Trace options from TraceOptions' fields (issue 21 item 4)
# --------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["trace", "diagram", "sweep"])
def test_trace_options_are_the_fields_of_trace_options(command):
    params = {p.name: p for p in main_group.commands[command].params}
    shared = [f for f in fields(TraceOptions) if f.metadata["option"]]
    assert len(shared) == 13
    for f in shared:
        p = params["uniform" if f.name == "adapt" else f.name]
        assert p.help == f.metadata["help"]
        if f.name == "adapt":
            assert p.is_flag and f.default is True  # --uniform turns adapt off
        elif f.name == "forced":
            assert p.multiple and f.default == ()
        else:
            assert p.default == f.default, f.name


@pytest.mark.parametrize("option, value, field", [
    ("--min-alignment", "1", "min_alignment"), ("--min-alignment", "-0.1", "min_alignment"),
    ("--ds", "0", "ds"), ("--fold-error", "-1e-9", "fold_error"), ("--forced", "inf", "forced"),
    ("--N-max", "20001", "N_max"), ("--max-steps", "0", "max_steps"),
])
def test_a_value_the_field_refuses_the_option_refuses(option, value, field, tmp_path, capsys):
    number = float(value)
    with pytest.raises(ValueError if field not in ("N_max", "max_steps") else (ValueError, TypeError)):
        TraceOptions(**{field: (number,) if field == "forced" else
                        int(number) if field in ("N_max", "max_steps") else number})
    code, out, err = run(["trace", "--gamma", "1", option, value, "--out", tmp_path / "t.h5"], capsys)
    assert_one_line_error(code, out, err, option)
    assert not (tmp_path / "t.h5").exists()


def test_relations_between_options_are_the_library_s_named_as_options(tmp_path, capsys):
    with pytest.raises(ValueError, match="need ds_min <= ds <= ds_max"):
        TraceOptions(ds=1.0)
    code, out, err = run(["trace", "--gamma", "1", "--ds", "1", "--out", tmp_path / "t.h5"], capsys)
    assert_one_line_error(code, out, err, "need --ds-min <= --ds <= --ds-max, got 1e-06, 1, 0.5")
    code, out, err = run(["diagram", "--gamma", "1", "--phi-min", "3", "--phi-max", "2", "--out", tmp_path / "d.h5"],
                         capsys)
    assert_one_line_error(code, out, err, "--phi-min must be below --phi-max")
