"""pyEIT 1.2.4's numbers on its own mesh (testdata/reference/pyeit), reproduced from Python:
voltages to 1e-10, Jacobian and one-step NOSER images (plain and normalised) to 1e-8 of the peak."""

import json

import numpy as np
import pytest

import eitskin

from conftest import reference


def load(name):
    return json.loads(reference("pyeit", name).read_text())


def relative(ours, theirs):
    theirs = np.asarray(theirs, dtype=float)
    return float(np.max(np.abs(np.asarray(ours) - theirs)) / np.max(np.abs(theirs)))


@pytest.fixture(scope="module")
def pyeit():
    data = load("square16_4k.json")
    m = data["mesh"]
    mesh = eitskin.mesh_from_pyeit(node=m["nodes"], element=m["triangles"], el_pos=m["electrode_nodes"])
    model = eitskin.ForwardModel(mesh, eitskin.Protocol.adjacent(16, skip_driven=True))
    return data, load("square16_4k_jacobian_recon.json"), model


def test_voltages_match_pyeit(pyeit):
    data, _, model = pyeit
    assert relative(model.measure(1.0), data["adjacent"]["v_homogeneous"]) < 1e-10
    inside = np.ones(len(model.mesh.triangles))
    inside[data["conductivity"]["inclusion"]["triangles"]] = 0.5
    assert relative(model.measure(inside), data["adjacent"]["v_inclusion"]) < 1e-10


def test_jacobian_and_images_match_pyeit(pyeit):
    data, recon, model = pyeit
    jacobian = model.jacobian(1.0)
    rows = np.asarray(recon["jacobian"]["rows_excitation0"])
    # pyEIT's J is -dv/dsigma.
    assert relative(-jacobian[: len(rows)], rows) < 1e-8
    assert relative(-jacobian.sum(axis=0), recon["jacobian"]["column_sums"]) < 1e-8

    v0 = np.asarray(data["adjacent"]["v_homogeneous"])
    v1 = np.asarray(data["adjacent"]["v_inclusion"])
    # pyEIT's "lm" prior is lambda * diag(J^T J): NOSER with exponent 1 and hyperparameter sqrt(lambda).
    plain = eitskin.one_step_matrix(jacobian, model.mesh, np.sqrt(0.1), prior="noser", exponent=1.0)
    assert relative(plain @ (v1 - v0), recon["noser_lambda0.1_plain"]["ds"]) < 1e-8
    normalised = eitskin.one_step_matrix(jacobian, model.mesh, np.sqrt(0.1), exponent=1.0, background=v0)
    assert relative(normalised @ (v1 / v0 - 1.0), recon["noser_lambda0.1_normalized"]["ds"]) < 1e-8


def test_a_pyeit_protocol_converts_in_one_call(pyeit):
    data, _, model = pyeit
    # pyEIT's adjacent protocol as its README states it: excitation i drives [i, i+1]; pairs
    # [n, m] = [(m+1) % 16, m] that touch no driven electrode; v = phi[n] - phi[m].
    ex_mat = np.array([[i, (i + 1) % 16] for i in range(16)])
    meas_mat = np.array(
        [[(m + 1) % 16, m, i] for i in range(16) for m in range(16) if not {m, (m + 1) % 16} & set(ex_mat[i])]
    )
    m = data["mesh"]
    mesh = eitskin.mesh_from_pyeit(node=m["nodes"], element=m["triangles"], el_pos=m["electrode_nodes"])
    protocol = eitskin.protocol_from_pyeit(ex_mat=ex_mat, meas_mat=meas_mat, n_el=16)
    assert len(protocol) == 208
    converted = eitskin.ForwardModel(mesh, protocol)
    assert relative(converted.measure(1.0), data["adjacent"]["v_homogeneous"]) < 1e-10
