"""The strain energy of the deformable bodies, recorded as a part of the potential energy
(issue 34: the overview's energy panel): against 1/2 q_f^T K_ff q_f from the body data, with
the rest of the potential energy equal to the gravity potential of the centre of mass; results
files written before it read with NaN."""

import h5py
import numpy as np

import flexmbd as fm
from flexmbd.plotting import plot_energy


def test_strain_energy_is_the_elastic_part_of_the_potential_energy(assert_close):
    example = fm.examples.tetrahedral_pendulum()
    result = fm.simulate(
        example.system, 0.2, example.step_size, solver=example.solver, output_interval=0.01
    )
    body = example.system._flexible[example.items["arm"].index]
    inv = body.invariants
    qf = result.elastic_coordinates("arm")
    k = np.asarray(inv.k_ff.toarray() if hasattr(inv.k_ff, "toarray") else inv.k_ff)
    strain = 0.5 * np.einsum("ti,ij,tj->t", qf, k, qf)
    assert strain.max() > 1e-6  # it bends
    assert_close(result.strain_energy, strain, rel=1e-10, abs=1e-14, what="strain energy")
    # The rest is gravity's: m g y of the centre of mass (g = 9.81 m/s^2 along -y).
    centre = (
        result.position("arm")
        + np.einsum(
            "tij,tj->ti", result.orientation("arm"), inv.first_moment + qf @ np.asarray(inv.i1).T
        )
        / inv.mass
    )
    gravity = inv.mass * 9.81 * centre[:, 1]
    assert_close(
        result.potential_energy - result.strain_energy, gravity, abs=1e-9 * np.abs(gravity).max(),
        what="gravity potential",
    )  # fmt: skip


def test_results_files_without_strain_energy_still_read(tmp_path):
    example = fm.examples.tetrahedral_pendulum()
    path = tmp_path / "old.h5"
    fm.simulate(example.system, 0.01, example.step_size, solver=example.solver, results_file=path)
    with h5py.File(path, "r+") as file:  # the layout of files written before: (n, 2)
        energy = file["energy"][:, :2]
        del file["energy"]
        file.create_dataset("energy", data=energy, maxshape=(None, 2))
    result = fm.read_results(path)
    assert np.isnan(result.strain_energy).all()
    assert np.isfinite(result.total_energy).all() and len(result.total_energy) > 5
    plot_energy(result)  # one potential curve, strain included
