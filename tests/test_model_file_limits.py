"""Model files under bad input (issue 28): size limits checked before YAML reads a file, YAML
1.1 surprises (base-60 numbers, tags that cannot read their value), nesting and cycles that
would exhaust the recursion, control characters, outputs checked on loading, model names that
would be paths, and tags that would run code. Each case is one ModelFileError naming the file,
the line and, where there is one, the key path."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

import flexmbd.model_file as model_file
from flexmbd.errors import ModelFileError
from flexmbd.model_file import load_model, simulate_model

ROOT = Path(__file__).parents[1]

# An arm turned by a driver from rest (0.1 (cos 2t - 1) rad), a beam and a solid block.
BASE = """\
name: limits
gravity: [0.0, -9.81, 0.0]
functions:
  swing: {type: harmonic, amplitude: 0.1, frequency: 2.0, phase: 1.5707963267948966, offset: -0.1}
bodies:
  - {name: arm, type: rigid, mass: 1.0, inertia: [0.1, 0.1, 0.1]}
  - name: rod
    type: flexible
    beam: {length: 1.0, elements: 2}
    material: {young_modulus: 1.0e+9, poisson_ratio: 0.3, density: 1000.0}
    section: {type: circle, radius: 0.01}
    reference: clamped
    reference_nodes: [0]
  - name: block
    type: flexible
    box: {lengths: [0.1, 0.1, 0.1], divisions: [1, 1, 1]}
    material: {young_modulus: 1.0e+9, poisson_ratio: 0.3, density: 1000.0}
    reference: clamped
    reference_nodes: x0
markers:
  - {name: pivot, body: ground}
  - {name: hinge, body: arm}
joints:
  - {name: drive, type: angle-driver, marker1: pivot, marker2: hinge, angle: swing}
simulation:
  end_time: 1.0
  step_size: 1.0e-3
"""


def line_of(text: str, needle: str) -> int:
    """The line (1-based) of the first `needle` in `text`."""
    return text[: text.index(needle)].count("\n") + 1


#: Lines of the base: of `end_time`, and the first line after it.
END = line_of(BASE, "end_time")
AFTER = BASE.count("\n") + 1


def write(tmp_path: Path, text: str, name: str = "model.yaml") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return path


def edited(*replacements: str) -> str:
    text = BASE
    for old, new in zip(replacements[::2], replacements[1::2], strict=True):
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


def refused(path: Path) -> ModelFileError:
    """The one error of loading `path`: a ModelFileError on one line naming the file."""
    with pytest.raises(ModelFileError) as caught:
        load_model(path)
    error = caught.value
    assert "\n" not in str(error), str(error)
    assert error.file == str(path)
    assert str(error).startswith(f"{path}: ")
    return error


def test_the_base_model_loads(tmp_path):
    """The base of every case here is valid: each case fails for its own edit."""
    model = load_model(write(tmp_path, BASE))
    assert set(model.bodies) == {"arm", "rod", "block"}
    assert model.file_stem == "model"  # the file's stem, not its name


# 1. Size limits, checked before YAML composes the file -----------------------------------------


class _NoYaml:
    """Stands for the YAML loader in tests that must be refused before YAML reads anything."""

    def __init__(self, *args, **kwargs):
        raise AssertionError("YAML was asked to read a file the limits refuse")


def test_a_long_list_is_refused_before_yaml_reads_it(tmp_path, monkeypatch):
    # A 2.4 MB file with a 1.2-million-item list took more than 30 s to compose before the
    # count of values refused it: the estimate of items is now checked on the raw text.
    items = ",".join(["0"] * 1_200_000)
    text = edited("functions:\n", f"functions:\n  table: [{items}]\n")
    path = write(tmp_path, text)
    assert path.stat().st_size > 2_400_000
    monkeypatch.setattr(model_file.reading, "_Loader", _NoYaml)
    error = refused(path)
    assert re.search(r"about 12000\d\d items .* more than the limit of 100000", str(error))
    assert error.line is None


def test_the_item_estimate_counts_commas_and_line_breaks(tmp_path, monkeypatch):
    items = BASE.count(",") + BASE.count("\n")
    monkeypatch.setattr(model_file.reading, "MAX_ITEMS", items + 10)
    # Ten more line breaks (CRLF counts once) or ten more commas: at the limit, read.
    assert load_model(write(tmp_path, (BASE + "#\n" * 10).replace("\n", "\r\n")))
    assert load_model(write(tmp_path, BASE + "#" + "," * 9 + "\n"))
    # One more: refused before YAML reads the file, with the estimate and the limit.
    monkeypatch.setattr(model_file.reading, "_Loader", _NoYaml)
    error = refused(write(tmp_path, BASE + "#\n" * 11))
    assert (
        f"holds about {items + 11} items (commas and line breaks), more than the limit of "
        f"{items + 10}: put meshes, matrices and long tables in mesh or body files" in str(error)
    )
    assert f"about {items + 11} items" in str(
        refused(write(tmp_path, BASE + "#" + "," * 10 + "\n"))
    )


def test_a_file_over_the_size_limit_is_refused_before_yaml_reads_it(tmp_path, monkeypatch):
    text = BASE + "# " + "x" * model_file.MAX_FILE_SIZE + "\n"
    path = write(tmp_path, text)
    monkeypatch.setattr(model_file.reading, "_Loader", _NoYaml)
    error = refused(path)
    assert f"has {path.stat().st_size} bytes, more than the limit of 4194304 (4 MiB)" in str(error)


def test_aliases_that_expand_a_small_file_are_refused(tmp_path):
    # Seven levels of ten aliases each: 10^7 values from a file of 700 bytes.
    lines = ["level0: &level0 [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]"]
    for k in range(1, 8):
        lines.append(f"level{k}: &level{k} [" + ", ".join([f"*level{k - 1}"] * 10) + "]")
    text = "\n".join(lines) + "\n" + BASE
    error = refused(write(tmp_path, text))
    assert "expands to more than 250000 values (through aliases?)" in str(error)


def test_the_example_model_files_are_well_within_the_limits():
    for path in sorted((ROOT / "examples" / "models").glob("*.yaml")):
        text = path.read_text()
        assert len(text.encode()) < model_file.MAX_FILE_SIZE / 100, path.name
        assert text.count(",") + text.count("\n") < model_file.MAX_ITEMS / 100, path.name
        load_model(path)


# 2. YAML 1.1 surprises ---------------------------------------------------------------------------


@pytest.mark.parametrize("value", ["1:30", "1:30.5", "-0:30", "1_0:00"])
def test_base_60_numbers_are_strings_that_the_schema_refuses(value, tmp_path):
    # YAML 1.1 reads `end_time: 1:30` as 90 (base 60): a silently different end time.
    error = refused(write(tmp_path, edited("end_time: 1.0", f"end_time: {value}")))
    assert str(error) == (
        f"{tmp_path / 'model.yaml'}: line {END}: simulation.end_time: Input should be a valid "
        f"number, got '{value}' (base-60 numbers such as 1:30 are not read: write 90)"
    )
    assert (error.line, error.key) == (END, "simulation.end_time")


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("2", 2.0),
        ("2.5", 2.5),
        ("1e1", 10.0),
        ("1E+1", 10.0),
        ("2.5e1", 25.0),
        ("2.5E-1", 0.25),
        ("1_000", 1000.0),
        ("010", 10.0),  # decimal, as in YAML 1.2 (YAML 1.1: octal 8)
        ("0x10", 16.0),
        ("+.5", 0.5),
        ("5.", 5.0),
    ],
)
def test_ordinary_numbers_are_numbers(text, value, tmp_path):
    model = load_model(write(tmp_path, edited("end_time: 1.0", f"end_time: {text}")))
    assert model.end_time == value


@pytest.mark.parametrize("value", [".inf", "-.inf", ".nan", ".NaN"])
def test_infinities_and_nans_are_read_and_refused_by_the_schema(value, tmp_path):
    error = refused(write(tmp_path, edited("end_time: 1.0", f"end_time: {value}")))
    assert f"line {END}: simulation.end_time: Input should be a finite number" in str(error)


@pytest.mark.parametrize(
    ("tagged", "message"),
    [
        ("!!bool abc", "'abc' is not a valid !!bool value"),
        ("!!int abc", "'abc' is not a valid !!int value"),
        ("!!int 1:30", "'1:30' is not a valid !!int value"),
        ("!!float 1:30", "'1:30' is not a valid !!float value"),
        ("!!float abc", "'abc' is not a valid !!float value"),
        ("!!timestamp abc", "'abc' is not a valid !!timestamp value"),
        ("!!int 0x", "'0x' is not a valid !!int value"),
    ],
)
def test_a_tag_that_cannot_read_its_value_names_the_line_and_key(tagged, message, tmp_path):
    # `mass: !!bool abc` raised a bare KeyError('abc') from the YAML constructor.
    text = edited(
        "{name: arm, type: rigid, mass: 1.0,", f"{{name: arm, type: rigid, mass: {tagged},"
    )
    error = refused(write(tmp_path, text))
    assert str(error) == f"{tmp_path / 'model.yaml'}: line 6: bodies[0].mass: {message}"
    assert (error.line, error.key) == (6, "bodies[0].mass")


def test_a_tag_on_a_key_that_cannot_read_it_names_the_key(tmp_path):
    error = refused(write(tmp_path, BASE + "!!int x: 1\n"))
    assert str(error).endswith(f"line {AFTER}: x: 'x' is not a valid !!int value")


def test_an_integer_too_large_for_the_api_names_the_item(tmp_path):
    # A node index of 10^22 made the preprocessor raise a bare OverflowError; it is refused
    # as a typed error naming the parameter (issue 28), at the line of its key.
    text = edited("reference_nodes: [0]", "reference_nodes: [10000000000000000000000]")
    error = refused(write(tmp_path, text))
    assert (
        f"line {line_of(BASE, 'reference_nodes: [0]')}: bodies[1].reference_nodes: "
        "reference_nodes must be integers within int64, got an integer of 74 bits"
    ) in str(error)


# 3. Nesting and cycles ----------------------------------------------------------------------------


@pytest.mark.parametrize("style", ["flow", "block"])
def test_deep_nesting_is_refused_while_reading(style, tmp_path):
    # 1000 levels made the composer raise RecursionError.
    if style == "flow":
        nested = "[" * 1000 + "]" * 1000
        text = BASE + f"extra: {nested}\n"
        # The file's mapping is the first level, `extra: ` and 63 brackets the next 64.
        where = f"line {AFTER}, column 71"
    else:
        text = BASE + "extra:\n" + "".join(" " * k + "-\n" for k in range(1000))
        where = f"line {AFTER + 64}, column 64"
    error = refused(write(tmp_path, text))
    assert str(error) == f"{tmp_path / 'model.yaml'}: {where}: nested more than 64 levels deep"


def test_nesting_within_the_limit_is_read(tmp_path):
    nested = "[" * 60 + "]" * 60
    error = refused(write(tmp_path, BASE + f"extra: {nested}\n"))
    assert "extra: unknown key 'extra'" in str(error)


def test_an_alias_inside_its_own_anchor_is_refused(tmp_path):
    error = refused(write(tmp_path, BASE + "extra: &self [1, *self]\n"))
    assert str(error).endswith(
        f"line {AFTER}: extra: nested more than 64 levels deep (an alias inside its anchor?)"
    )


@pytest.mark.parametrize(
    ("functions", "cycle"),
    [
        ("{swing: swing}", "swing -> swing"),
        ("{swing: back, back: swing}", "swing -> back -> swing"),
        ("{swing: a, a: b, b: c, c: a}", "a -> b -> c -> a"),
        ("{swing: 1.0, a: b, b: a}", "a -> b -> a"),  # unused functions are checked too
    ],
)
def test_functions_that_name_each_other_in_a_cycle_are_refused(functions, cycle, tmp_path):
    # A function naming itself, or naming one that names it back, raised RecursionError.
    text = re.sub(r"(?m)^  swing: .*\n", "", BASE)
    text = text.replace("functions:\n", f"functions: {functions}\n")
    error = refused(write(tmp_path, text))
    first = cycle.split(" -> ")[0]
    assert str(error).endswith(
        f"line 3: functions.{first}: the functions refer to each other in a cycle: {cycle}"
    )
    assert error.key == f"functions.{first}"


def test_an_unknown_name_in_functions_is_refused_even_if_unused(tmp_path):
    text = edited("functions:\n", "functions:\n  spare: missing\n")
    error = refused(write(tmp_path, text))
    assert str(error).endswith(
        "line 4: functions.spare: unknown function 'missing' (functions: spare, swing)"
    )


def test_a_long_chain_of_named_functions_is_followed_without_recursion(tmp_path):
    chain = "".join(f"  f{k}: f{k + 1}\n" for k in range(5000)) + "  f5000: swing\n"
    text = edited("functions:\n", "functions:\n" + chain, "angle: swing}", "angle: f0}")
    model = load_model(write(tmp_path, text))
    direct = load_model(write(tmp_path, BASE, "direct.yaml"))
    a = simulate_model(model, end_time=0.003)
    b = simulate_model(direct, end_time=0.003)
    np.testing.assert_array_equal(a.coordinates, b.coordinates)


# 4. Control characters -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("character", "name"),
    [
        ("\x00", "U+0000 (NUL)"),
        ("\x07", "U+0007 (BEL)"),
        ("\x1b", "U+001B (ESC)"),
        ("\x7f", "U+007F (DEL)"),
        ("\x9b", "U+009B"),
    ],
)
def test_a_control_character_names_its_line_and_column(character, name, tmp_path):
    # NUL or BEL anywhere gave a yaml ReaderError that escaped the loader.
    text = edited("  - {name: arm,", f"  - {{name: a{character}rm,")
    error = refused(write(tmp_path, text))
    assert str(error) == (
        f"{tmp_path / 'model.yaml'}: line 6, column 13: control character {name} is not "
        "allowed in YAML; remove it"
    )
    assert error.line == 6


def test_escaped_control_characters_in_quotes_reach_the_checks(tmp_path):
    """The escape "\\a" is YAML text, not a raw control character: the name check refuses it."""
    error = refused(write(tmp_path, edited("name: limits", 'name: "lim\\aits"')))
    assert "line 1: name: a model name is a plain name" in str(error)
    assert "no control or invisible characters (U+0007)" in str(error)


# 5. Outputs checked on loading -------------------------------------------------------------------

BAD_OUTPUTS = {
    "{body: rod, quantity: deflection, node: 99}": (
        "outputs[0].node: body 'rod' has no node with id 99 (its 3 nodes have ids 1 to 3)"
    ),
    "{body: rod, quantity: node_positions, nodes: [1, 2, 7]}": (
        "outputs[0].nodes[2]: body 'rod' has no node with id 7"
    ),
    "{body: rod, quantity: deflection, node: 2, chord: [1, 4]}": (
        "outputs[0].chord[1]: body 'rod' has no node with id 4"
    ),
    "{body: rod, quantity: deflection, node: 2, chord: [3, 3]}": (
        "outputs[0].chord: a chord needs two different nodes, got [3, 3]"
    ),
    "{body: rod, quantity: position, node: 2}": (
        "outputs[0].node: node is only for deflection outputs of flexible bodies"
    ),
    "{joint: drive, quantity: reaction_force, nodes: [1]}": (
        "outputs[0].nodes: nodes is only for node_displacements and node_positions outputs"
    ),
    "{quantity: total_energy, chord: [1, 2]}": (
        "outputs[0].chord: chord is only for deflection outputs of flexible bodies"
    ),
    "{body: rod, quantity: stresses}": (
        "outputs[0].quantity: body 'rod' has no solid elements: stresses are those of solid "
        "elements (beams have section_forces)"
    ),
    "{body: block, quantity: section_forces}": (
        "outputs[0].quantity: body 'block' has no beam elements with a section"
    ),
    "{body: arm, quantity: deflection, node: 1}": "outputs[0].body: 'arm' is not a flexible body",
    "{body: nobody, quantity: position}": "outputs[0].body: unknown body 'nobody' (bodies: ",
}


@pytest.mark.parametrize("output", list(BAD_OUTPUTS))
def test_outputs_are_checked_when_the_file_is_loaded(output, tmp_path):
    # `outputs: [{body: rod, quantity: deflection, node: 99}]` failed only after simulating.
    text = BASE + f"outputs:\n  - {output}\n"
    error = refused(write(tmp_path, text))
    assert f"line {AFTER + 1}: {BAD_OUTPUTS[output]}" in str(error), str(error)
    assert error.key.startswith("outputs[0]")


def test_every_output_accepted_on_loading_gives_its_values(tmp_path):
    outputs = [
        "{body: rod, quantity: deflection, node: 3}",
        "{name: sag, body: rod, quantity: deflection, node: 2, chord: [1, 3]}",
        "{body: rod, quantity: node_positions, nodes: [1, 3]}",
        "{body: rod, quantity: node_displacements}",
        "{body: rod, quantity: section_forces}",
        "{body: block, quantity: stresses}",
        "{body: block, quantity: elastic_velocities}",
        "{body: arm, quantity: angular_velocity}",
        "{body: ground, quantity: position}",
        "{joint: drive, quantity: multipliers}",
        "{quantity: total_energy}",
    ]
    text = BASE + "outputs:\n" + "".join(f"  - {o}\n" for o in outputs)
    model = load_model(write(tmp_path, text))
    result = simulate_model(model, end_time=0.002)
    values = model.output_values(result)
    assert len(values) == len(outputs)
    for label, value in values.items():
        assert len(value) == len(result.time), label
        assert np.all(np.isfinite(value)), label
    np.testing.assert_array_equal(
        values["rod node_positions"], result.node_positions("rod", [1, 3])
    )


def test_two_outputs_with_one_label_are_refused(tmp_path):
    # output_values returns the outputs by label: the second of two labels hid the first.
    outputs = "  - {body: rod, quantity: deflection, node: 3}\n" * 2
    error = refused(write(tmp_path, BASE + "outputs:\n" + outputs))
    assert str(error).endswith(
        f"line {AFTER + 2}: outputs[1]: duplicate output label 'rod deflection' (first at line "
        f"{AFTER + 1}): give each output its own name"
    )


# 6. Model names are plain names -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "problem"),
    [
        ("../x", "no path separators ('/', '\\'), got '../x'"),
        ("/abs/x", "no path separators"),
        ("a\\\\b", "no path separators"),
        ("..", "it may not start with a dot, got '..'"),
        (".hidden", "it may not start with a dot"),
        ("a\\0b", "no control or invisible characters (U+0000)"),
        ("a\\u202eb", "no control or invisible characters (U+202E)"),
    ],
)
def test_a_model_name_that_would_be_a_path_is_refused(name, problem, tmp_path):
    # `name: ../x` made `flexmbd run` write its results outside the working folder.
    error = refused(write(tmp_path, edited("name: limits", f'name: "{name}"')))
    assert str(error).startswith(
        f"{tmp_path / 'model.yaml'}: line 1: name: a model name is a plain name (the stem of "
        "the results' file names): "
    )
    assert problem in str(error), str(error)
    assert error.key == "name"


@pytest.mark.parametrize(
    ("name", "stem"),
    [
        ("four-bar", "four-bar"),
        ("slider crank: v2", "slider crank_ v2"),
        ('a<b>c"d|e?f*g', "a_b_c_d_e_f_g"),
        ("CON", "CON_"),
        ("nul.v2", "nul.v2_"),
        ("Pendel ä", "Pendel ä"),
        ("run. ", "run"),
        ("ü" * 100, "ü" * 60),
    ],
)
def test_the_file_stem_is_a_plain_file_name(name, stem, tmp_path):
    # The model file's stem names the outputs: a file whose own stem is nothing (".yaml")
    # falls back to the model's name, made a stem the same way.
    model = load_model(
        write(tmp_path, edited("name: limits", f"name: {json.dumps(name)}"), "...yaml")
    )
    assert model.name == name
    assert model.file_stem == stem
    assert len(model.file_stem.encode()) <= 120
    assert os.path.basename(model.file_stem) == model.file_stem


def test_the_file_stem_is_the_model_files_stem(tmp_path):
    text = edited("name: limits\n", "")
    assert load_model(write(tmp_path, text, "pendulum.v2.yaml")).file_stem == "pendulum.v2"
    assert load_model(write(tmp_path, text, "...yaml")).file_stem == "model"
    assert load_model(write(tmp_path, BASE, "crank: v2.yaml")).file_stem == "crank_ v2"
    assert load_model(write(tmp_path, BASE, "four_bar.yaml")).file_stem == "four_bar"


# 7. Tags that would run code stay refused; files that are not regular files ---------------


@pytest.mark.parametrize(
    "tagged",
    [
        "!!python/object/apply:os.mkdir ['{path}']",
        "!!python/object/apply:os.mkdir {{args: ['{path}']}}",
        "!!python/object:os.mkdir {{}}",
        "!!python/module:os ''",
        "!!python/name:os.mkdir ''",
    ],
)
def test_python_tags_stay_refused_anywhere(tagged, tmp_path):
    target = tmp_path / "created"
    for place in ("value", "alias", "key"):
        if place == "value":
            text = edited("inertia: [0.1, 0.1, 0.1]", "inertia: " + tagged.format(path=target))
        elif place == "alias":
            text = "extra: &evil " + tagged.format(path=target) + "\n" + BASE + "more: *evil\n"
        else:
            text = BASE + "? " + tagged.format(path=target) + "\n: 1\n"
        error = refused(write(tmp_path, text))
        assert re.search(r"the tag '!!python/[a-z/]+(:[a-z.]+)?' is not allowed", str(error))
        assert not target.exists()


def test_a_folder_or_a_pipe_is_not_read(tmp_path):
    (tmp_path / "folder.yaml").mkdir()
    assert "not a regular file" in str(refused(tmp_path / "folder.yaml"))
    if hasattr(os, "mkfifo"):
        # Opening a pipe blocks until something writes to it: refused without opening it.
        os.mkfifo(tmp_path / "pipe.yaml")
        assert "not a regular file" in str(refused(tmp_path / "pipe.yaml"))


# 7. Messages stay short; step bounds are checked on loading ------------------------------------


@pytest.mark.parametrize(
    "old, new",
    [
        ("marker2: hinge", "marker2: " + "h" * 1_000_000),
        ("type: angle-driver", "type: " + "a" * 1_000_000),
        ("- {name: arm,", "- {name: " + "b" * 1_000_000 + ","),
        ("angle: swing}", "angle: " + "s" * 100_000 + "}"),
    ],
)
def test_a_long_name_is_shortened_in_the_message(old, new, tmp_path):
    # Regression (fuzz suite): an unknown marker, type or function of a megabyte was echoed
    # whole, with the list of known names, in a message of megabytes.
    error = refused(write(tmp_path, edited(old, new)))
    assert len(str(error)) < 1000, len(str(error))


def test_many_known_names_are_listed_up_to_a_limit(tmp_path):
    markers = "".join(f"  - {{name: m{k}, body: arm}}\n" for k in range(500))
    text = edited("markers:\n", "markers:\n" + markers, "marker2: hinge", "marker2: nothing")
    error = refused(write(tmp_path, text))
    assert "... (482 more)" in str(error) and len(str(error)) < 1000


@pytest.mark.parametrize(
    "solver, key, words",
    [
        ("{type: generalized-alpha, min_step_size: 1.0e+300}", "min_step_size", "larger"),
        ("{type: explicit, max_step_size: 1.0e-6}", "max_step_size", "smaller"),
    ],
)
def test_step_bounds_that_do_not_fit_the_step_size_are_refused_on_loading(
    solver, key, words, tmp_path
):
    # Regression (fuzz suite): refused only by the run, with a message that named neither
    # key and printed 1e300 with 301 digits.
    error = refused(write(tmp_path, BASE + f"solver: {solver}\n"))
    assert error.key == f"solver.{key}"
    assert f"{words} than simulation.step_size 0.001" in str(error)
    assert len(str(error)) < 300
