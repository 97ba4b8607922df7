"""One spelling per concept across subcommands, help text in plain words on every option, and one
resolution of the parameters of every command that simulates."""

from __future__ import annotations

import argparse
import importlib
import re
from dataclasses import replace

import pytest

from gearsim.cli.main import build_parser
from gearsim.dynamics.parameters import ModelParameters
from gearsim.physical.units import load_gear
from gearsim.study.config import project_root


def _options():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = []

    def walk(name, p):
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for n, sp in a.choices.items():
                    walk(f"{name} {n}", sp)
            elif not isinstance(a, (argparse._HelpAction, argparse._VersionAction)):
                out.append((name, a))

    for n, sp in sub.choices.items():
        walk(n, sp)
    return out


OPTIONS = _options()


def test_every_option_has_help():
    missing = [(cmd, a.option_strings or [a.dest]) for cmd, a in OPTIONS
               if not a.help or a.help == argparse.SUPPRESS or not a.help.strip()]
    assert not missing, missing


# concept -> the one spelling; the others may survive only as aliases of the same option
SPELLINGS = {
    "config files": ("--configfile", {"--config-file", "--config", "--cfg"}),
    "catalogue": ("--catalogue", {"--db", "--catalog", "--database"}),
    "output file": ("--out", {"--save", "--output", "-o"}),
}


@pytest.mark.parametrize("concept", sorted(SPELLINGS))
def test_one_spelling_per_concept(concept):
    """An old spelling is accepted only beside the canonical one, on the same option."""
    canonical, old = SPELLINGS[concept]
    for cmd, a in OPTIONS:
        names = set(a.option_strings)
        if names & old:
            assert canonical in names, (cmd, sorted(names))


def test_point_save_is_an_alias_of_out():
    args = build_parser().parse_args(["point", "-w", "1", "--save", "x.parquet"])
    assert args.out == "x.parquet"


def test_every_output_option_has_o():
    """`-o` is the short form of `--out` on every command that writes a file."""
    lacking = [cmd for cmd, a in OPTIONS if "--out" in a.option_strings
               and "-o" not in a.option_strings]
    assert not lacking, lacking


MARKUP = re.compile(r"``|:(mod|func|class|data|meth):`")


def test_help_is_plain_words():
    """No reStructuredText markup in `gearsim --help` or any option's help."""
    parser = build_parser()
    assert not MARKUP.search(parser.format_help()), parser.format_help()
    marked = [(cmd, a.option_strings) for cmd, a in OPTIONS if a.help and MARKUP.search(a.help)]
    assert not marked, marked
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sp in sub.choices.items():
        assert not MARKUP.search(sp.description or ""), name


#: command -> its own arguments beside the shared parameter options
SIMULATING = {
    "point": [],
    "orbit": [],
    "attractors": [],
    "basins": ["-o", "basins.parquet"],
    "continue": ["--name", "xi", "--from", "0.09", "--to", "0.1"],
    "sweep": ["--name", "standard"],
}


@pytest.mark.parametrize("command", sorted(SIMULATING))
def test_simulating_commands_resolve_the_same_parameters(command, tmp_path):
    """`--configfile --gear --rpm` give every simulating command the same parameter set: the
    gear file's, converted by the geometry (GearGeometry.to_model_parameters at 6000 rpm, an
    independent path from the option's axis conversion), with the study file's xi on top."""
    study = tmp_path / "my.yaml"
    study.write_text("parameters: {xi: 0.09}\n")
    gear_file = project_root() / "config/gears/standard.yaml"
    argv = [command, *SIMULATING[command], "--configfile", str(study), "--gear",
            str(gear_file), "--rpm", "6000", "--set", "eps=0.3"]
    args = build_parser().parse_args(argv)
    module = importlib.import_module(args._run.__module__)
    got = module.resolve(args).params
    gear = replace(load_gear(gear_file), speed_rpm=6000.0)
    expected = ModelParameters.from_mapping(
        {**gear.to_model_parameters().to_dict(), "xi": 0.09, "eps": 0.3})
    for name, value in expected.to_dict().items():
        if isinstance(value, str):
            assert getattr(got, name) == value, name
        else:
            assert getattr(got, name) == pytest.approx(value, rel=1e-12, abs=1e-15), name
    rated = load_gear(gear_file)
    assert rated.to_model_parameters().w == pytest.approx(1.0, rel=1e-9)  # the file's speed
    assert got.w == pytest.approx(6000.0 / rated.speed_rpm, rel=1e-9)


def test_rpm_without_a_gear_file_is_one_line(capsys):
    from gearsim.cli.main import main

    assert main(["orbit", "--rpm", "6000"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--gear" in err[0]


def test_omega_and_rpm_together_are_refused(capsys):
    from gearsim.cli.main import main

    gear_file = str(project_root() / "config/gears/standard.yaml")
    assert main(["point", "-w", "1", "--gear", gear_file, "--rpm", "6000"]) == 2
    assert "twice" in capsys.readouterr().err
