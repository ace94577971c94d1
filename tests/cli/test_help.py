"""``--help`` of the tool and of every command: it works, names the command, and describes
every option with its default; the defaults shown are the ones used, and the library's."""

import argparse
import inspect

import pytest

from stereodeblur.cli import build_parser, main

COMMANDS = [
    [],
    ["deblur"],
    ["sceneflow"],
    ["demo"],
    ["synth"],
    ["synth", "planar"],
    ["synth", "objects"],
    ["synth", "average"],
    ["render-view"],
    ["kernels"],
    ["bench"],
    ["bench", "planar"],
    ["bench", "sceneflow"],
    ["bench", "paper"],
]
# Actions every parser has that take no value of the run.
NO_DEFAULT = (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction)


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c) or "stereodeblur")
def test_help(command, capsys):
    assert main([*command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: stereodeblur " + " ".join(command))


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("stereodeblur ")


def parsers(parser=None, path=()):
    """``(command path, parser)`` of the tool and of every command and subcommand."""
    parser = build_parser() if parser is None else parser
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from parsers(child, (*path, name))


def _help_text(parser, action) -> str:
    """The help of ``action`` as ``--help`` prints it (``%(default)s`` and the like expanded)."""
    return parser._get_formatter()._expand_help(action)


def problems(parser) -> list[str]:
    """What is missing from the help of ``parser``'s own arguments and subcommands."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            found += [
                f"command {c.dest!r} has no help" for c in action._choices_actions if not c.help
            ]
        if isinstance(action, NO_DEFAULT):
            continue
        name = "/".join(action.option_strings) or action.dest
        if not action.help or action.help == argparse.SUPPRESS:
            found.append(f"{name} has no help")
            continue
        if not action.option_strings or action.required:
            continue  # positional or required: no default to state
        text = _help_text(parser, action)
        default = action.default
        if isinstance(default, bool):
            wanted = f"default: {'on' if default else 'off'}"
        elif default is None:
            wanted = "default"
        else:
            wanted = str(default)
        if "default" not in text or wanted not in text:
            found.append(f"{name}: help does not state its default {default!r}: {text!r}")
    return found


ALL_PARSERS = list(parsers())


@pytest.mark.parametrize(
    "path, parser", ALL_PARSERS, ids=[" ".join(p) or "-" for p, _ in ALL_PARSERS]
)
def test_every_option_has_help_that_states_its_default(path, parser):
    assert problems(parser) == []


def test_the_walk_reaches_every_command():
    assert sorted(" ".join(p) for p, _ in ALL_PARSERS) == sorted(" ".join(c) for c in COMMANDS)


def test_the_check_finds_a_missing_help_or_default():
    """The check above can fail: options without help or without their default are found."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--a", default=3, help="a number")
    parser.add_argument("--b", help="text")
    parser.add_argument("--c", action="store_true", help="a switch (default: on)")
    parser.add_argument("--d", default="x")
    parser.add_argument("--e", default=3, help="a number (default: %(default)s)")
    parser.add_argument("--f", action="store_true", help="a switch (default: off)")
    found = problems(parser)
    assert [line.split(" ", 1)[0] for line in found] == ["--a:", "--b:", "--c:", "--d"], found


def test_settings_defaults_shown_are_the_ones_used(capsys):
    from stereodeblur.settings import PAPER_CG, PAPER_IRLS, DeblurSettings

    assert main(["deblur", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    used = DeblurSettings()
    assert f"(default: {used.num_samples}; paper: 70)" in out
    assert f"(default: {used.num_irls}; paper: {PAPER_IRLS})" in out
    assert f"(default: {used.num_cg}; paper: {PAPER_CG})" in out
    assert f"default: {used.interpolation})" in out


def test_default_segment_rule_is_the_estimators():
    from stereodeblur.cli.settings_options import SEGMENTS_RULE
    from stereodeblur.sceneflow.from_gt import default_num_segments

    assert (
        SEGMENTS_RULE
        == f"about {default_num_segments((480, 640))} at 640x480, scaled with the image area"
    )
    assert default_num_segments((960, 1280)) == 4 * default_num_segments((480, 640))


def test_synth_sizes_are_the_librarys():
    from stereodeblur.cli.synth import SIZE
    from stereodeblur.synth.objects import write_object_set
    from stereodeblur.synth.planar import write_planar_set

    for writer in (write_planar_set, write_object_set):
        assert inspect.signature(writer).parameters["size"].default == SIZE


def test_the_python_api_samples_as_the_command_line():
    """The blur builders' default interpolation is DeblurSettings' and the CLI's."""
    from stereodeblur.blur import displacement, homography
    from stereodeblur.settings import DeblurSettings

    args = build_parser().parse_args(["deblur", "s", "-o", "o"])
    for builder in (
        homography.homography_blur,
        homography.homography_blur_reference,
        displacement.displacement_blur,
        displacement.displacement_blur_reference,
    ):
        default = inspect.signature(builder).parameters["interpolation"].default
        assert default == DeblurSettings().interpolation == args.interpolation, builder


def test_old_option_spellings_are_gone(capsys):
    """One name per idea: frames are chosen with --frames in every command, and no prefix of
    an option (argparse's abbreviations) stands for it."""
    assert main(["sceneflow", "s", "-o", "o", "--frame", "1"]) == 2
    assert main(["bench", "sceneflow", "--frame", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("unrecognized arguments: --frame 1") == 2, err
