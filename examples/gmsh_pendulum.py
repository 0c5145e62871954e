"""A flexible pendulum from a Gmsh-meshed solid: an aluminium arm 0.4 x 0.04 x 0.02 m with a
round lightening hole, built and meshed with 4-node tetrahedra by Gmsh's Python API, reduced by
Craig-Bampton (8 fixed-interface modes, the body frame on the hinged end face "root"), hinged at
the centroid of that face and released horizontally under gravity.

Without damping, at spectral radius 1, the energy is conserved to second order in the step:
the example checks the drift against the energy exchanged (1e-5). The results are written to
``gmsh_pendulum.h5`` during the run, with a ParaView series (``gmsh_pendulum_vtu/``) and a
rendered animation (``gmsh_pendulum.gif``) of the deformed mesh and the interactive viewer
(``gmsh_pendulum.html``, coloured by stress), in the folder given as the
first argument (default: a temporary folder).

``python examples/gmsh_pendulum.py --mesh FILE`` only writes the mesh to FILE.

Needs gmsh (``pip install flexmbd[mesh]``).
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import flexmbd as fm
from flexmbd.fe import Material, body_from_mesh, von_mises


def mesh_arm(path: Path) -> None:
    """The arm in Gmsh (OpenCASCADE): a box minus a cylinder, the end face x = 0 a physical
    surface "root", the end face x = 0.4 m a physical surface "tip", the volume a physical
    volume "arm". ``examples/meshes/arm.msh``, the mesh the documentation's commands use, is
    this mesh (``python examples/gmsh_pendulum.py --mesh examples/meshes/arm.msh``)."""
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("arm")
        box = gmsh.model.occ.addBox(0.0, -0.02, -0.01, 0.4, 0.04, 0.02)
        hole = gmsh.model.occ.addCylinder(0.25, 0.0, -0.01, 0.0, 0.0, 0.02, 0.012)
        (volume,), _ = gmsh.model.occ.cut([(3, box)], [(3, hole)])
        gmsh.model.occ.synchronize()
        root = [
            tag
            for dim, tag in gmsh.model.getEntities(2)
            if np.allclose(gmsh.model.occ.getCenterOfMass(dim, tag)[0], 0.0)
        ]
        tip = [
            tag
            for dim, tag in gmsh.model.getEntities(2)
            if np.allclose(gmsh.model.occ.getCenterOfMass(dim, tag)[0], 0.4)
        ]
        gmsh.model.addPhysicalGroup(2, root, name="root")
        gmsh.model.addPhysicalGroup(2, tip, name="tip")
        gmsh.model.addPhysicalGroup(3, [volume[1]], name="arm")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.01)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def main(folder: Path) -> int:
    mesh_file = folder / "arm.msh"
    mesh_arm(mesh_file)
    material = Material(7.0e10, 0.33, 2700.0)
    data = body_from_mesh(
        mesh_file,
        material,
        reference="interface",
        modes="craig-bampton",
        mode_count=8,
        interfaces=["root"],
    )
    print(
        f"{mesh_file.name}: {data.node_count} nodes, {len(data.elements['tet4'])} tetrahedra, "
        f"mass {data.invariants.mass:.4f} kg; {data.elastic_coordinate_count} modes, first "
        f"frequencies {np.round(data.frequencies[:3], 1)} Hz"
    )
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    arm = system.add_flexible_body(data, name="arm")
    hinge = system.add_revolute_joint(
        system.add_marker(system.ground), system.add_node_set_marker(arm, "root"), name="hinge"
    )
    results = folder / "gmsh_pendulum.h5"
    result = fm.simulate(
        system,
        1.0,
        5e-4,
        output_interval=0.01,
        solver=fm.GeneralizedAlpha(1.0),
        results_file=results,
        metadata={"source": __file__},
    )
    print(result)
    exchanged = np.ptp(result.potential_energy)
    drift = np.max(np.abs(result.total_energy - result.total_energy[0])) / exchanged
    print(f"energy drift relative to the energy exchanged: {drift:.1e}")
    force = np.linalg.norm(result.reaction_force(hinge), axis=1)
    print(f"largest hinge force {force.max():.2f} N (weight {9.81 * data.invariants.mass:.2f} N)")
    stress = von_mises(result.stresses(arm))
    print(f"largest von Mises stress {stress.max() / 1e6:.3f} MPa")
    back = fm.read_results(results)
    same = np.array_equal(back.node_positions(arm), result.node_positions(arm))
    print(f"results file {results}: {len(back)} records, node positions identical: {same}")
    from flexmbd.animation import render_animation, render_image, write_vtu_series

    pvd = write_vtu_series(back, folder / "gmsh_pendulum_vtu", name="gmsh_pendulum")
    render_animation(back, folder / "gmsh_pendulum.gif")
    render_image(back, folder / "gmsh_pendulum.png", record=len(back) // 2)
    print(f"ParaView series {pvd}, animation {folder / 'gmsh_pendulum.gif'}")
    # The interactive viewer (needs plotly: pip install flexmbd[view]), coloured by stress.
    page = fm.view(back, folder / "gmsh_pendulum.html", color_by="stress")
    print(f"viewer {page} ({page.stat().st_size / 1e6:.1f} MB): open it in a browser")
    return int(drift > 1e-5 or not same)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--mesh":
        mesh_arm(Path(sys.argv[2]))
        raise SystemExit(0)
    if len(sys.argv) > 1:
        raise SystemExit(main(Path(sys.argv[1])))
    with tempfile.TemporaryDirectory() as folder:
        raise SystemExit(main(Path(folder)))
