"""Input limits checked before the work (issue 28): mesh sizes are estimated before any array
is made or Gmsh meshes, and refused above a limit with the estimate in the message."""

from __future__ import annotations

import time

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.errors import ArgumentTypeError, InvalidParameterError
from flexmbd.fe import shapes


@pytest.mark.parametrize(
    "element, elements, nodes",
    [
        ("tet4", "3.84e+08", "6.45e+07"),
        ("hex8", "6.4e+07", "6.45e+07"),
        ("tet10", "3.84e+08", "5.1"),
    ],
)
def test_a_box_of_too_many_elements_is_refused_before_it_is_made(element, elements, nodes):
    # Issue 28: divisions [400, 400, 400] ran out of memory (numpy MemoryError) after minutes.
    start = time.perf_counter()
    with pytest.raises(InvalidParameterError, match="max_elements") as info:
        shapes.box((1.0, 1.0, 1.0), (400, 400, 400), element)
    assert time.perf_counter() - start < 1.0
    message = str(info.value)
    assert f"about {elements} elements and {nodes}" in message
    assert "GB" in message and "divisions 400 x 400 x 400" in message
    assert info.value.item == "mesh size"


def test_the_box_estimate_is_exact_and_the_limit_can_be_moved():
    for element in ("hex8", "tet4", "tet10"):
        mesh = shapes.box((1.0, 0.5, 0.2), (4, 3, 2), element)
        count = len(mesh.elements[element])
        shapes.box((1.0, 0.5, 0.2), (4, 3, 2), element, max_elements=count)
        with pytest.raises(
            InvalidParameterError, match=f"about {count} elements and {len(mesh.nodes)} nodes"
        ):
            shapes.box((1.0, 0.5, 0.2), (4, 3, 2), element, max_elements=count - 1)


def test_bad_box_divisions_are_typed_errors():
    for divisions in [(2.5, 1, 1), ("a", 1, 1), (1, 1, 0)]:
        with pytest.raises(InvalidParameterError):
            shapes.box((1.0, 1.0, 1.0), divisions)
    with pytest.raises(InvalidParameterError):
        shapes.box((1.0, float("inf"), 1.0), (1, 1, 1))


@pytest.mark.parametrize(
    "arguments, parameter, match",
    [
        ({"lengths": fm.MarkerId(99)}, "lengths", "lengths must be numbers, got MarkerId"),
        ({"lengths": "abc"}, "lengths", "lengths must be numbers"),
        ({"lengths": (1.0, 2.0)}, "lengths", "lengths must be three finite numbers"),
        ({"lengths": (1.0, -1.0, 1.0)}, "lengths", "three positive lengths"),
        ({"origin": fm.BodyId(1)}, "origin", "origin must be numbers"),
        ({"origin": (0.0, float("nan"), 0.0)}, "origin", "origin must be three finite"),
        ({"divisions": (1, 1, 0)}, "divisions", "three positive divisions"),
        (
            {"element": np.array(["hex8", "tet4"])},
            "element",
            "box elements are hex8, .* or tet10, got array",
        ),
    ],
    ids=["id", "string", "two", "negative", "id origin", "nan origin", "zero", "array"],
)
def test_box_arguments_of_the_wrong_type_name_the_parameter(arguments, parameter, match):
    # Issue 28 (fuzz): box(lengths=<an id>) raised a bare TypeError (float() argument must be
    # a string or a real number), an array as element a bare ValueError (truth value).
    call = {"lengths": (1.0, 0.1, 0.1), "divisions": (2, 1, 1), **arguments}
    with pytest.raises(InvalidParameterError, match=match) as info:
        shapes.box(**call)
    assert info.value.item == parameter


@pytest.mark.parametrize(
    "divisions",
    [b"abc", "abc", "2", bytearray(b"\x02\x01\x01"), (True, 1, 1), (2.5, 1, 1), None, [[2, 1, 1]]],
    ids=["bytes", "str", "digit", "bytearray", "bool", "fraction", "none", "nested"],
)
def test_box_divisions_that_are_not_integers_are_argument_type_errors(divisions):
    # Issue 28 (fuzz): divisions=b"abc" made a box of 97 x 98 x 99 cells (the bytes' codes).
    with pytest.raises(ArgumentTypeError, match="integer divisions") as info:
        shapes.box((1.0, 0.1, 0.1), divisions)
    assert info.value.item == "divisions"


def test_box_divisions_are_three_or_one_positive_integers():
    for divisions in [(1, 1), (1, 1, 1, 1)]:
        with pytest.raises(InvalidParameterError, match="three divisions") as info:
            shapes.box((1.0, 0.1, 0.1), divisions)
        assert info.value.item == "divisions"
    one = shapes.box((1.0, 0.1, 0.1), 2)
    assert len(one.elements["hex8"]) == 8
    assert len(shapes.box((1.0, 0.1, 0.1), [2]).nodes) == len(one.nodes)
    assert len(shapes.box((1.0, 0.1, 0.1), np.array([3, 1, 1])).elements["hex8"]) == 3
    assert len(shapes.box((1.0, 0.1, 0.1), (3.0, 1, 1)).elements["hex8"]) == 3
    with pytest.raises(InvalidParameterError, match="three positive divisions"):
        shapes.box((1.0, 0.1, 0.1), -1)


def test_gmsh_meshes_far_finer_than_the_geometry_are_refused_before_meshing():
    # Issue 28: a size far below the geometry made Gmsh abort the process (out of memory).
    pytest.importorskip("gmsh")
    start = time.perf_counter()
    with pytest.raises(InvalidParameterError, match=r"about 6e\+12 elements .*size 0.0001"):
        shapes.cylinder(0.5, 1.0, size=1e-4)
    with pytest.raises(InvalidParameterError, match="max_elements"):
        shapes.tapered_link(1.0, (0.1, 0.1), (0.05, 0.05), size=1e-5)
    assert time.perf_counter() - start < 2.0
    # The estimate (6 per size^3 of the bounding boxes) is above what Gmsh makes: a mesh
    # allowed by it is made.
    estimate = 6 * 0.1 * 0.1 * 0.2 / 0.02**3
    mesh = shapes.cylinder(0.05, 0.2, size=0.02, order=1, max_elements=1.01 * estimate)
    assert 0 < len(mesh.elements["tet4"]) <= estimate
    with pytest.raises(InvalidParameterError, match="about 150. elements .* limit of 100 "):
        shapes.cylinder(0.05, 0.2, size=0.02, order=1, max_elements=100)
