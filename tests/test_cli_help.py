"""``continuum-sim --help`` speaks to users: what the tool does and one line per command, no developer notes."""

from __future__ import annotations

from continuum_sim.cli import build_parser, main


def _help(capsys) -> str:
    assert main(["--help"]) == 0
    return capsys.readouterr().out


def test_top_level_help_describes_the_tool_and_every_command(capsys):
    text = _help(capsys)
    assert "continuum robot" in text and "sample-removal task" in text
    # no module docstring or source-level wording
    for developer in ("argument parser", "``", "subcommand", "its handler", "parser.py", "continuum_sim.cli"):
        assert developer not in text, developer
    commands = next(a for a in build_parser()._actions if a.dest == "command")
    for name in commands.choices:
        assert name in text
    helps = {action.dest: action.help for action in commands._choices_actions}
    assert set(helps) == set(commands.choices), "every command has a one-line help"
    assert all(h and "\n" not in h for h in helps.values())
    assert "continuum-sim run" in text and "COMMAND --help" in text
