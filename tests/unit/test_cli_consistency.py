"""One spelling per concept across subcommands, and help text on every option."""

from __future__ import annotations

import argparse

import pytest

from gearsim.cli.main import build_parser


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
