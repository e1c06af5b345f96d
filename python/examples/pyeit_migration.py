"""From pyEIT to eitskin, side by side, on pyEIT's own mesh (testdata/reference/pyeit).

pyEIT (1.2.4):                                   eitskin:
    mesh_obj = mesh.create(16, h0=0.048, ...)        mesh = eitskin.mesh_from_pyeit(mesh_obj)
    protocol_obj = protocol.create(16, 1, 1)         protocol = eitskin.Protocol.adjacent(16)
    fwd = EITForward(mesh_obj, protocol_obj)         model = eitskin.ForwardModel(mesh, protocol)
    v0 = fwd.solve_eit(perm=1.0)                     v0 = model.measure(1.0)
    eit = JAC(mesh_obj, protocol_obj)                J = model.jacobian(1.0)   # = -pyEIT's J
    eit.setup(p=0.5, lamb=0.1, method="lm")          H = eitskin.one_step_matrix(J, mesh, 0.1 ** 0.5, exponent=1.0)
    ds = eit.solve(v1, v0, normalize=False)          ds = H @ (v1 - v0)        # same sign as pyEIT's ds

    python pyeit_migration.py [path/to/square16_4k.json]
"""
import json
import pathlib
import sys

import numpy as np

import eitskin

# The file given, else the repository's copy of pyEIT's results.
default = pathlib.Path(__file__).resolve().parents[2] / "testdata" / "reference" / "pyeit" / "square16_4k.json"
data = json.loads(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else default).read_text())
m = data["mesh"]
mesh = eitskin.mesh_from_pyeit(node=m["nodes"], element=m["triangles"], el_pos=m["electrode_nodes"])
model = eitskin.ForwardModel(mesh, eitskin.Protocol.adjacent(16))  # point electrodes, as pyEIT
sigma = np.ones(len(mesh.triangles))
sigma[data["conductivity"]["inclusion"]["triangles"]] = 0.5
v0, v1 = model.measure(1.0), model.measure(sigma)
print("voltages vs pyEIT:", np.max(np.abs(v0 - data["adjacent"]["v_homogeneous"])) / np.max(v0))
H = eitskin.one_step_matrix(model.jacobian(1.0), mesh, 0.1**0.5, exponent=1.0)  # pyEIT "lm", lamb = 0.1
ds = H @ (v1 - v0)
peak = np.argmin(ds)
print(f"image peak {ds[peak]:.3f} S/m at {mesh.centroids()[peak].round(3)} (pyEIT: -0.227 at (0.428, 0.012))")
