"""HDF5 body files: exact round trips, the file layout, version and format checks."""

from __future__ import annotations

import copy
import dataclasses
import math
import subprocess
import sys

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm
from flexmbd.errors import InvalidModelError, InvalidParameterError
from flexmbd.fe import Material, Section, body_file, build_body, shapes, straight_beam
from flexmbd.fe.body import BODY_DATA_VERSION, FlexibleBodyData, Invariants, ReferenceConditions
from flexmbd.fe.body_file import BODY_FILE_FORMAT, load_body, save_body


def spd_sparse(n: int, seed: int, fmt: str = "csc") -> sp.spmatrix:
    """A sparse symmetric positive definite matrix (n x n)."""
    a = sp.random(n, n, density=0.3, random_state=seed)
    return (a @ a.T + n * sp.identity(n)).asformat(fmt)


def make_body(modal: bool = True) -> FlexibleBodyData:
    """Two tetrahedra clamped at three nodes; with ``modal`` three modes and dense invariants
    (some of them sparse), else nodal coordinates and None for the modal fields. The reference
    conditions and invariants are given as dicts (the constructor converts them)."""
    rng = np.random.default_rng(3)
    nodes = np.array(
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]]
    )
    free_dofs = np.arange(9, 15, dtype=np.int64)
    n_free = len(free_dofs)
    n_f = 3 if modal else n_free
    # Dense and sparse blocks mixed: each must come back as it was.
    i_kl = [
        [
            rng.normal(size=(n_f, n_f)) if (row + column) % 2 else spd_sparse(n_f, 3 * row + column)
            for column in range(3)
        ]
        for row in range(3)
    ]
    stiffness, mass = spd_sparse(15, 1), spd_sparse(15, 2)
    modes = rng.normal(size=(n_free, n_f)) if modal else None
    # K_ff and M_ff must be the nodal matrices reduced to the elastic coordinates.
    k_ff, m_ff = (matrix[free_dofs][:, free_dofs].tocsc() for matrix in (stiffness, mass))
    if modal:
        k_ff, m_ff = (modes.T @ (matrix @ modes) for matrix in (k_ff, m_ff))
    return FlexibleBodyData(
        nodes=nodes,
        node_ids=np.array([101, 102, 103, 104, 105], dtype=np.int64),
        elements={"tet4": np.array([[0, 1, 2, 3], [1, 2, 3, 4]], dtype=np.int64)},
        element_ids={"tet4": np.array([11, 12], dtype=np.int64)},
        # Not in alphabetical order: the order must survive.
        node_sets={
            "tip": np.array([4], dtype=np.int64),
            "clamp": np.array([0, 1, 2], dtype=np.int64),
            "a/b %2F": np.array([3], dtype=np.int64),
            ".": np.array([], dtype=np.int64),
        },
        material={"young_modulus": 2.1e11, "poisson_ratio": 0.3, "density": 7850.0},
        section=None,
        dofs_per_node=3,
        stiffness=stiffness,
        mass=mass,
        mass_kind="consistent",
        reference={"kind": "clamped", "nodes": np.array([0, 1, 2]), "free_dofs": free_dofs},
        modes=modes,
        frequencies=np.array([12.5, 40.25, 77.0]) if modal else None,
        mode_kind="free-free" if modal else None,
        invariants={
            "mass": 1.2345678901234567,
            "first_moment": rng.normal(size=3),
            # A second moment of mass is symmetric positive semi-definite (load_body checks).
            "second_moment": (lambda a: a @ a.T)(rng.normal(size=(3, 3))),
            "i1": rng.normal(size=(3, n_f)),
            "i_kl": i_kl,
            "ibar": rng.normal(size=(3, 3, n_f)),
            "k_ff": k_ff,
            "m_ff": m_ff,
        },
        units={"length": "mm", "mass": "t", "time": "s"},
        metadata={"source": "two_tets.inp", "created": "2024-05-01T12:00:00", "note": "héllo"},
    )


def assert_identical(a, b, where: str = "body") -> None:
    """Exact equality: same types, dtypes, shapes, bit-identical values, same key order."""
    assert type(a) is type(b), f"{where}: {type(a)} != {type(b)}"
    if isinstance(a, FlexibleBodyData | Invariants | ReferenceConditions):
        for field in dataclasses.fields(a):
            assert_identical(
                getattr(a, field.name), getattr(b, field.name), f"{where}.{field.name}"
            )
    elif sp.issparse(a):
        assert a.format == b.format and a.shape == b.shape and a.dtype == b.dtype, where
        assert (a != b).nnz == 0, where
        if a.format in ("csc", "csr"):
            for name in ("data", "indices", "indptr"):
                assert_identical(getattr(a, name), getattr(b, name), f"{where}.{name}")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        assert np.array_equal(a, b) and a.tobytes() == b.tobytes(), where
    elif isinstance(a, dict):
        assert list(a) == list(b), f"{where}: keys {list(a)} != {list(b)}"
        for key in a:
            assert_identical(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_identical(x, y, f"{where}[{index}]")
    elif isinstance(a, float):
        assert a == b or (math.isnan(a) and math.isnan(b)), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


@pytest.mark.parametrize("modal", [True, False], ids=["modal", "nodal"])
def test_round_trip_is_exact(tmp_path, modal):
    body = make_body(modal)
    original = copy.deepcopy(body)
    path = tmp_path / "body.h5"
    save_body(body, path)
    loaded = load_body(path)
    assert_identical(original, loaded)
    assert_identical(body, original)  # saving does not touch the data
    assert loaded.version == BODY_DATA_VERSION
    assert loaded.elastic_coordinate_count == (3 if modal else 6)
    i_kl = loaded.invariants.i_kl
    assert sp.issparse(i_kl[0][0]) and isinstance(i_kl[0][1], np.ndarray)
    assert not list(tmp_path.glob(".*tmp"))  # the temporary file is gone


def test_file_layout(tmp_path):
    path = tmp_path / "body.h5"
    save_body(make_body(modal=False), path)
    with h5py.File(path, "r") as file:
        assert file.attrs["format"] == BODY_FILE_FORMAT
        assert file.attrs["version"] == BODY_DATA_VERSION
        assert file.attrs["units"] == '{"length": "mm", "mass": "t", "time": "s"}'
        assert file["nodes"].dtype == np.float64 and file["nodes"].shape == (5, 3)
        assert file["node_ids"].dtype == np.int64
        assert file["elements/tet4"].dtype == np.int64
        stiffness = file["stiffness"]
        assert stiffness.attrs["type"] == "sparse" and stiffness.attrs["format"] == "csc"
        assert sorted(stiffness) == ["data", "indices", "indptr", "shape"]
        assert list(stiffness["shape"][...]) == [15, 15]
        for name in ("section", "modes", "frequencies", "mode_kind"):
            assert file[name].attrs["type"] == "none" and file[name].shape is None
        assert list(file["node_sets"]) == ["tip", "clamp", "a%2Fb %252F", "%2E"]
        assert file["invariants/i_kl"].attrs["type"] == "list"
        assert file["invariants/i_kl/0/0"].attrs["type"] == "sparse"
        assert file["invariants/i_kl/0/1"].attrs["type"] == "ndarray"
        # The typed reference conditions and invariants are stored as the dicts they were.
        assert file["reference"].attrs["type"] == "dict"
        assert list(file["reference"]) == ["kind", "nodes", "free_dofs"]
        assert file["invariants"].attrs["type"] == "dict"
        assert list(file["invariants"]) == [
            "mass",
            "first_moment",
            "second_moment",
            "i1",
            "ibar",
            "i_kl",
            "k_ff",
            "m_ff",
        ]
        assert file["invariants/mass"].attrs["type"] == "float"


def test_sparse_formats_and_scalars_round_trip(tmp_path):
    # Values of every kind in a free-form dictionary field (``section``, which nothing reads
    # on loading).
    dense = np.arange(12.0).reshape(3, 4)
    int64_indices = sp.csc_matrix(
        (np.ones(2), np.array([0, 1], dtype=np.int64), np.array([0, 1, 2], dtype=np.int64)),
        shape=(2, 2),
    )
    int64_indices.indices = np.array([0, 1], dtype=np.int64)
    int64_indices.indptr = np.array([0, 1, 2], dtype=np.int64)
    values = {
        "csr": sp.csr_matrix(dense),
        "coo": sp.coo_matrix(dense),
        "csc_array": sp.csc_array(dense),
        "lil": sp.lil_matrix(dense),
        "int64 indices": int64_indices,
        "float32": np.ones((2, 2), dtype=np.float32),
        "bool": np.array([True, False]),
        "empty": np.zeros((0, 3)),
        "big endian": np.arange(3, dtype=">f8"),
        "numpy scalar": np.float32(1.5),
        "numpy int": np.int64(-4),
        "0-d array": np.array(2.5),
        "nan": float("nan"),
        "int": 7,
        "flag": True,
        "tuple": (1, "two", None),
        "nested": {"deeper": {"x": -0.0}},
    }
    body = dataclasses.replace(make_body(), section=values)
    path = tmp_path / "body.h5"
    save_body(body, path)
    loaded = load_body(path)
    assert_identical(body.section, loaded.section)
    assert loaded.section["int64 indices"].indices.dtype == np.int64
    assert math.copysign(1.0, loaded.section["nested"]["deeper"]["x"]) == -1.0


@pytest.mark.parametrize("compression", ["gzip", "lzf"])
def test_large_arrays_are_compressed(tmp_path, compression):
    small = make_body()
    n_free, n_modes = 60_000, 8
    # Fields that fit each other (load_body checks): 20,000 nodes, no nodal matrices.
    body = dataclasses.replace(
        small,
        nodes=np.linspace(0.0, 1.0, n_free).reshape(-1, 3),
        node_ids=np.arange(1, n_free // 3 + 1, dtype=np.int64),
        stiffness=None,
        mass=None,
        # Smooth mode shapes compress well.
        modes=np.sin(np.outer(np.linspace(0.0, 10.0, n_free), np.arange(1, n_modes + 1))),
        frequencies=np.arange(1.0, n_modes + 1),
        reference=dataclasses.replace(small.reference, free_dofs=np.arange(n_free, dtype=np.int64)),
        invariants=dataclasses.replace(
            small.invariants,
            i1=np.zeros((3, n_modes)),
            ibar=np.zeros((3, 3, n_modes)),
            i_kl=[[np.eye(n_modes)] * 3] * 3,
            k_ff=np.eye(n_modes),
            m_ff=np.eye(n_modes),
        ),
    )
    path = tmp_path / "big.h5"
    save_body(body, path, compression=compression)
    with h5py.File(path, "r") as file:
        assert file["modes"].compression == compression
        assert file["reference/free_dofs"].compression == compression
        assert file["elements/tet4"].compression is None  # small arrays stay contiguous
    assert path.stat().st_size < 0.8 * (body.modes.nbytes + n_free * 8)
    assert_identical(body, load_body(path))


def test_newer_version_is_refused(tmp_path):
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    with h5py.File(path, "r+") as file:
        file.attrs["version"] = np.int64(BODY_DATA_VERSION + 1)
    message = f"written by a newer flexmbd: version {BODY_DATA_VERSION + 1} > {BODY_DATA_VERSION}"
    with pytest.raises(InvalidModelError, match=message) as info:
        load_body(path)
    assert info.value.item == f"file '{path}'"


def test_not_a_body_file(tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as file:
        file.create_dataset("x", data=np.zeros(3))
    with pytest.raises(InvalidModelError, match="is not a flexmbd body file") as info:
        load_body(other)
    assert str(other) in str(info.value)

    with h5py.File(other, "a") as file:
        file.attrs["format"] = "something-else"
    with pytest.raises(InvalidModelError, match="format 'something-else'"):
        load_body(other)

    text = tmp_path / "notes.h5"
    text.write_text("not HDF5\n")
    with pytest.raises(InvalidModelError, match="not an HDF5 file"):
        load_body(text)

    with pytest.raises(FileNotFoundError):
        load_body(tmp_path / "missing.h5")


def test_damaged_file_names_the_field(tmp_path):
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    with h5py.File(path, "r+") as file:
        del file["mass"]
    with pytest.raises(InvalidModelError, match="no field 'mass'"):
        load_body(path)


def test_overwrite_existing_file(tmp_path):
    path = tmp_path / "body.h5"
    save_body(make_body(modal=True), path)
    save_body(make_body(modal=False), path)
    assert load_body(path).modes is None


@pytest.mark.parametrize(
    "change, match",
    [
        ({"metadata": {3: "x"}}, "dictionary keys must be strings"),
        ({"metadata": {"": "x"}}, "empty dictionary key"),
        ({"section": {"obj": np.array([{}])}}, "section/obj.*dtype object"),
        ({"section": {"set": {1, 2}}}, "section/set.*type set"),
        ({"version": BODY_DATA_VERSION + 1}, "layout version"),
        ({"units": {"length": 1}}, "units must be a dict of str"),
    ],
)
def test_values_that_cannot_be_stored(tmp_path, change, match):
    body = dataclasses.replace(make_body(), **change)
    path = tmp_path / "body.h5"
    with pytest.raises(InvalidParameterError, match=match):
        save_body(body, path)
    assert not path.exists()
    assert not list(tmp_path.iterdir())  # no temporary file left behind


def test_craig_bampton_reference_conditions_keep_their_layout(tmp_path):
    # The optional entries of the reference conditions are members of the "reference" group
    # (in the order of the dict they were) when set, and absent when None.
    mesh = shapes.box((0.4, 0.05, 0.05), (4, 1, 1), "hex8")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        Material(2.1e11, 0.3, 7800.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=3,
        interfaces=["x0", "x1"],
        interface_kind="rbe3",
    )
    path = tmp_path / "body.h5"
    save_body(body, path)
    with h5py.File(path, "r") as file:
        assert list(file["reference"]) == [
            "kind",
            "nodes",
            "free_dofs",
            "interfaces",
            "interface_kind",
            "mode_count",
            "interface_weights",
        ]
        assert file["reference/interfaces"].attrs["type"] == "list"
        assert file["reference/mode_count"].attrs["type"] == "int"
    loaded = load_body(path)
    assert_identical(body, loaded)
    assert loaded.reference.interface_kind == "rbe3" and loaded.reference.mode_count == 3
    assert len(loaded.reference.interface_weights) == 2


def test_unknown_entries_in_the_file_name_the_entry(tmp_path):
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    with h5py.File(path, "r+") as file:
        file.create_dataset("invariants/extra", data=1.0).attrs["type"] = "float"
    with pytest.raises(InvalidModelError, match="'invariants' has unknown entry 'extra'") as info:
        load_body(path)
    assert str(path) in str(info.value)
    assert info.value.item == f"file '{path}'"


def test_bad_arguments(tmp_path):
    with pytest.raises(InvalidParameterError, match="expects a FlexibleBodyData"):
        save_body({"nodes": []}, tmp_path / "x.h5")
    with pytest.raises(InvalidParameterError, match="compression"):
        save_body(make_body(), tmp_path / "x.h5", compression="zstd")


# Issue 28: damaged body files and values that do not make a body. Each case raised a raw
# OSError, KeyError, RuntimeError or scipy error, or loaded silently; each must now be an
# InvalidModelError whose message names the file and the field.


def damaged(path, member: str, value=None, *, kind: str | None = None, delete: bool = False):
    """Replace (or delete) a member of a body file; the new dataset keeps the old ``type``
    unless `kind` is given."""
    with h5py.File(path, "r+") as file:
        old_kind = file[member].attrs.get("type")
        del file[member]
        if not delete:
            dataset = file.create_dataset(member, data=value)
            if (kind or old_kind) is not None:
                dataset.attrs["type"] = kind or old_kind


STRUCTURAL_DAMAGE = {
    "deleted list item": (dict(member="invariants/i_kl/1/0", delete=True), "i_kl/1/0"),
    "deleted dict entry": (
        dict(member="reference/free_dofs", delete=True),
        "'reference' has no entry 'free_dofs'",
    ),
    "deleted invariant": (
        dict(member="invariants/k_ff", delete=True),
        "'invariants' has no entry 'k_ff'",
    ),
    "deleted reference kind": (
        dict(member="reference/kind", delete=True),
        "'reference' has no entry 'kind'",
    ),
    "string for a number": (
        dict(member="dofs_per_node", value="three", kind="str"),
        "'dofs_per_node' must be 3 or 6",
    ),
    "bytes for a float": (
        dict(member="invariants/mass", value=np.bytes_(b"1.5")),
        "invariants/mass' should hold a number",
    ),
    "text array for nodes": (dict(member="nodes", value=np.array([b"a", b"b"])), "'nodes'"),
    "nodes of two columns": (dict(member="nodes", value=np.zeros((5, 2))), r"\(5, 2\)"),
    "float free dofs": (
        dict(member="reference/free_dofs", value=np.arange(6.0)),
        r"reference\[\"free_dofs\"\]' must be an integer array",
    ),
    "free dofs out of range": (
        dict(member="reference/free_dofs", value=np.arange(20, 26)),
        "coordinate index 20",
    ),
    "element out of range": (
        dict(member="elements/tet4", value=np.array([[0, 1, 2, 3], [1, 2, 3, 99]])),
        "node index 99",
    ),
    "modes of the wrong shape": (dict(member="modes", value=np.zeros((4, 3))), "'modes'"),
    "invariant of the wrong shape": (
        dict(member="invariants/i1", value=np.zeros((3, 2))),
        r"invariants\[\"i1\"\]' has shape \(3, 2\)",
    ),
    "sparse index out of range": (
        dict(member="stiffness/indices", value=np.full(1, 10**6, dtype=np.int32)),
        "'stiffness'",
    ),
    "sparse shape of three entries": (
        dict(member="stiffness/shape", value=np.array([15, 15, 15])),
        "'stiffness' has an invalid shape",
    ),
}


@pytest.mark.parametrize("case", list(STRUCTURAL_DAMAGE))
def test_damaged_body_files_name_the_file_and_field(tmp_path, case):
    change, match = STRUCTURAL_DAMAGE[case]
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    if case == "sparse index out of range":
        # Same length as before, one index far outside the 15 x 15 matrix: scipy's products
        # would read outside the arrays (a segmentation fault, not an error).
        with h5py.File(path, "r") as file:
            indices = file["stiffness/indices"][...]
        indices[-1] = 10**6
        change = dict(change, value=indices)
    damaged(path, **change)
    with pytest.raises(InvalidModelError, match=match) as info:
        load_body(path)
    assert str(path) in str(info.value)
    assert info.value.item == f"file '{path}'"


@pytest.mark.parametrize(
    "member, value, match",
    [
        ("nodes", np.full((5, 3), np.nan), "'nodes': node 101 has non-finite coordinates"),
        ("modes", np.full((6, 3), np.nan), "'modes' has non-finite entries"),
        ("invariants/mass", -1.0, r"'invariants\[\"mass\"\]': the mass must be finite and > 0"),
        ("invariants/second_moment", -np.eye(3), "positive semi-definite"),
        ("invariants/second_moment", np.diag([1.0, 1.0, -0.5]), "positive semi-definite"),
        ("invariants/second_moment", np.triu(np.ones((3, 3))), "symmetric"),
        ("invariants/first_moment", np.array([0.0, np.inf, 0.0]), "non-finite"),
        ("material/density", -7850.0, r"'material\[\"density\"\]' must be finite and > 0"),
        ("material/young_modulus", np.nan, r"'material\[\"young_modulus\"\]' must be finite"),
        ("material/poisson_ratio", 0.5, "between -1 and 0.5, got 0.5"),
        ("frequencies", np.array([-12.5, 40.25, 77.0]), "finite numbers >= 0 \\(Hz\\), got -12.5"),
        ("frequencies", np.array([12.5, 40.25]), "'frequencies' has 2 entries for 3 modes"),
        ("node_ids", np.array([101, 102, 103, 102, 105]), "repeats node id 102 \\(nodes 1 and 3"),
    ],
    ids=[
        "nan nodes",
        "nan modes",
        "negative mass",
        "negative J0",
        "indefinite J0",
        "asymmetric J0",
        "infinite s0",
        "negative density",
        "nan young modulus",
        "poisson ratio 0.5",
        "negative frequency",
        "frequencies short",
        "repeated node id",
    ],
)
def test_values_that_do_not_make_a_body_are_refused_on_load(tmp_path, member, value, match):
    # Issue 28: NaN nodes, NaN modes and a second moment of mass that is not positive
    # semi-definite were loaded without a word.
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    damaged(path, member, value)
    with pytest.raises(InvalidModelError, match=match) as info:
        load_body(path)
    assert str(path) in str(info.value)


def test_bad_damping_and_interfaces_are_refused_on_load(tmp_path):
    # A body file's damping and Craig-Bampton interface weights were loaded unchecked
    # (NaN Rayleigh coefficients, a negative ratio, NaN weights).
    from flexmbd.fe.body import _replace

    path = tmp_path / "body.h5"
    body = make_body()
    for damping, match in (
        ({"rayleigh": (np.nan, 0.0), "modal": None}, "Rayleigh coefficients"),
        ({"rayleigh": None, "modal": -0.1}, "damping ratio must be finite and >= 0"),
    ):
        save_body(_replace(body, damping=damping), path)
        with pytest.raises(InvalidModelError, match=match):
            load_body(path)
    reference = dataclasses.replace(
        body.reference,
        interfaces=[np.array([0, 1, 2])],
        interface_kind="rbe3",
        interface_weights=[np.array([1.0, np.nan, 1.0])],
    )
    save_body(_replace(body, reference=reference), path)
    with pytest.raises(InvalidModelError, match="weights must be finite and positive in sum"):
        load_body(path)
    reference = dataclasses.replace(reference, interfaces=[np.array([0, 1, 9])])
    save_body(_replace(body, reference=reference, metadata={}), path)
    with pytest.raises(InvalidModelError, match=r"interfaces\"\]\[0\]' holds node index 9"):
        load_body(path)


def test_truncated_body_files_fail_fast(tmp_path):
    # A truncated file must fail at once (no SWMR retries of the metadata reads): the load
    # runs in a child process that is killed after 20 s, and must take well under 5 s.
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    size = path.stat().st_size
    for keep in (size // 2, size - 64):
        cut = tmp_path / f"cut{keep}.h5"
        cut.write_bytes(path.read_bytes()[:keep])
        code = (
            "import sys, time\n"
            "from flexmbd.errors import InvalidModelError\n"
            "from flexmbd.fe import load_body\n"
            "start = time.perf_counter()\n"
            "try:\n"
            "    load_body(sys.argv[1])\n"
            "except InvalidModelError as error:\n"
            "    print(time.perf_counter() - start, error)\n"
        )
        done = subprocess.run(
            [sys.executable, "-c", code, str(cut)], capture_output=True, text=True, timeout=20
        )
        assert done.returncode == 0, done.stderr
        seconds, message = done.stdout.split(" ", 1)
        assert float(seconds) < 5.0
        assert str(cut) in message and "truncated or damaged" in message


def test_bit_flips_give_a_body_or_a_typed_error(tmp_path):
    # Every byte of the file's metadata flipped in turn (the first 4 kB hold the superblock,
    # the root group and the first object headers; data flips just change numbers): each
    # load gives a body or an InvalidModelError naming the file, never another exception.
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    original = path.read_bytes()
    flipped = tmp_path / "flipped.h5"
    outcomes = {"body": 0, "error": 0}
    for offset in range(0, 4096, 19):
        data = bytearray(original)
        data[offset] ^= 0xFF
        flipped.write_bytes(bytes(data))
        try:
            load_body(flipped)
            outcomes["body"] += 1
        except InvalidModelError as error:
            assert str(flipped) in str(error)
            outcomes["error"] += 1
    assert outcomes["error"] > 0


DATA_INDICES_INDPTR = ("data", "indices", "indptr")


def test_sparse_matrices_with_unsorted_or_duplicate_indices_load_canonical(tmp_path):
    # Issue 28 (fuzz): a body file whose sparse matrix had unsorted indices loaded as it was,
    # and System.add_flexible_body then sorted the body's read-only arrays in place
    # (ValueError 'WRITEBACKIFCOPY base is read-only'). A matrix stored with unsorted or
    # duplicate indices (which add up) reads back as the same matrix in canonical form.
    nodes, elements = straight_beam(0.5, 3)
    body = build_body(
        nodes,
        elements,
        Material(2.1e11, 0.3, 7800.0),
        section=Section.circle(0.01),
        reference="clamped",
        reference_nodes=[0],
    )
    original = body.invariants.i_kl[1][1]
    assert sp.isspmatrix_csc(original) and original.has_canonical_format
    path = tmp_path / "body.h5"
    save_body(body, path)
    member = "invariants/i_kl/1/1"
    with h5py.File(path, "r") as file:
        data, indices, indptr = (file[f"{member}/{name}"][...] for name in DATA_INDICES_INDPTR)
    # Each column in reverse order, and the first entry of the first column with two or more
    # split into two halves.
    order = np.concatenate(
        [np.arange(start, end)[::-1] for start, end in zip(indptr[:-1], indptr[1:], strict=True)]
    )
    column = int(np.flatnonzero(np.diff(indptr) >= 2)[0])
    at = indptr[column]
    data, indices = data[order], indices[order]
    data = np.concatenate([data[:at], [data[at] / 2, data[at] / 2], data[at + 1 :]])
    indices = np.concatenate([indices[: at + 1], indices[at:]]).astype(indices.dtype)
    indptr = indptr.copy()
    indptr[column + 1 :] += 1
    for name, value in zip(DATA_INDICES_INDPTR, (data, indices, indptr), strict=True):
        damaged(path, f"{member}/{name}", value)

    loaded = load_body(path)
    matrix = loaded.invariants.i_kl[1][1]
    assert matrix.has_canonical_format
    for name in DATA_INDICES_INDPTR:
        np.testing.assert_array_equal(getattr(matrix, name), getattr(original, name))
    assert matrix.indices.dtype == indices.dtype
    assert not matrix.indices.flags.writeable
    system = fm.System()
    system.add_flexible_body(loaded, name="beam")
    np.testing.assert_array_equal(loaded.invariants.i_kl[1][1].indices, original.indices)


def test_a_damaged_global_heap_is_refused_by_the_check_shared_with_results_files(tmp_path):
    # The HDF5 global heap scan is one function (flexmbd._hdf5) used by the readers of body
    # and results files: a collection whose size runs past the end of the file is refused
    # before HDF5 reads it (HDF5 would loop for ever or crash).
    import struct

    from flexmbd import _hdf5, results_file
    from flexmbd.fe import body_file

    assert body_file.global_heap_damage is results_file.global_heap_damage
    assert body_file.global_heap_damage is _hdf5.global_heap_damage
    path = tmp_path / "body.h5"
    save_body(make_body(), path)
    assert _hdf5.global_heap_damage(path) is None
    data = bytearray(path.read_bytes())
    heap = data.index(_hdf5.HEAP_SIGNATURE)
    data[heap + 8 : heap + 16] = struct.pack("<Q", 1 << 40)
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(bytes(data))
    assert "global heap collection at byte" in _hdf5.global_heap_damage(damaged)
    with pytest.raises(InvalidModelError, match="global heap collection") as info:
        load_body(damaged)
    assert str(damaged) in str(info.value) and "truncated or damaged" in str(info.value)
    assert info.value.item == f"file '{damaged}'"


@pytest.mark.parametrize("limit", [None, 0], ids=["templates", "too-large-for-templates"])
def test_bodies_copied_from_templates_read_back_as_each_models_own(tmp_path, monkeypatch, limit):
    """Results files copy a body this process wrote before for the same content (HDF5 object
    copy): two builds of the same rod share it, another diameter does not, and every file
    reads back its own model's body, bit for bit; bodies above the templates' size are
    written directly."""
    if limit is not None:
        monkeypatch.setattr(body_file, "_TEMPLATE_BYTES", limit)
    models = [
        fm.examples.flexible_slider_crank(rod_diameter=d).system.compile()
        for d in (6e-3, 6e-3, 7e-3, 6e-3)
    ]
    for k, model in enumerate(models):
        fm.simulate(model, 2e-3, 1e-3, results_file=tmp_path / f"{k}.h5")
    for k, model in enumerate(models):
        back = fm.read_results(tmp_path / f"{k}.h5").flexible[2]
        assert_identical(back, model.flexible_bodies[2], f"file {k}")
    assert (
        models[0].flexible_bodies[2].invariants.mass != models[2].flexible_bodies[2].invariants.mass
    )
    with h5py.File(tmp_path / "3.h5") as file:
        assert file["flexible/2/stiffness"].attrs["type"] == "sparse"
        assert file["flexible/2"].attrs["format"] == BODY_FILE_FORMAT


def test_a_file_that_is_no_body_file_is_not_replaced(tmp_path):
    # Regression: `flexmbd preprocess mesh.inp -o model.yaml` replaced the model file (and
    # save_body any file) by a body file.
    body = make_body(modal=False)
    other = tmp_path / "model.yaml"
    other.write_text("name: mine\n")
    with pytest.raises(InvalidParameterError, match="exists and is not a flexmbd body file"):
        save_body(body, other)
    assert other.read_text() == "name: mine\n"
    path = tmp_path / "body.h5"
    save_body(body, path)
    save_body(body, path)  # a body file is replaced
    import meshio

    from flexmbd.cli import main

    box = fm.fe.shapes.box((1.0, 0.1, 0.1), (2, 1, 1), "tet4")
    mesh = tmp_path / "bar.vtu"
    meshio.write(mesh, meshio.Mesh(box.nodes, [("tetra", box.elements["tet4"])]))
    argv = ["preprocess", str(mesh), "-o", str(other), "-E", "2e11", "--poisson-ratio", "0.3"]
    assert main([*argv, "--density", "7800"]) == 2
    assert other.read_text() == "name: mine\n"
