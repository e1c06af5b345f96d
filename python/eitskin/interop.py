"""Interop with pyEIT and matplotlib."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ._eitskin import Image, Mesh, Protocol


def mesh_from_pyeit(mesh: Any = None, *, node: Any = None, element: Any = None, el_pos: Sequence[int] | None = None) -> Mesh:
    """An eitskin mesh from a pyEIT mesh object or its arrays.

    Parameters
    ----------
    mesh : pyeit.mesh.PyEITMesh, optional
        Its ``node`` (n, 2 or 3), ``element`` (t, 3) and ``el_pos`` (electrode nodes) are used.
    node, element, el_pos : array_like, optional
        The same arrays given directly (when ``mesh`` is None).

    Returns
    -------
    Mesh
        Point electrodes at the ``el_pos`` nodes, in pyEIT's electrode order.
    """
    if mesh is not None:
        node, element, el_pos = mesh.node, mesh.element, mesh.el_pos
    if node is None or element is None or el_pos is None:
        raise ValueError("give a pyEIT mesh, or node, element and el_pos")
    node = np.asarray(node, dtype=float)[:, :2]
    return Mesh(node, np.asarray(element, dtype=np.int64), [np.array([e]) for e in np.asarray(el_pos).ravel()])


def protocol_from_pyeit(
    protocol: Any = None, *, ex_mat: Any = None, meas_mat: Any = None, n_el: int | None = None
) -> Protocol:
    """An eitskin protocol from a pyEIT protocol object or its arrays.

    Parameters
    ----------
    protocol : pyeit.eit.protocol.PyEITProtocol, optional
        Its ``ex_mat`` (excitations, 2), ``meas_mat`` (measurements, 3) and ``n_el`` are used.
    ex_mat : array_like, optional
        Per excitation [a, b]: unit current in at electrode a, out at b.
    meas_mat : array_like, optional
        Per measurement [n, m, excitation]: v = phi[n] - phi[m] under that excitation.
    n_el : int, optional
        Number of electrodes (default: one more than the largest electrode named).

    Returns
    -------
    Protocol
        The same stimulations and measurements, in pyEIT's order and sign.
    """
    if protocol is not None:
        ex_mat, meas_mat, n_el = protocol.ex_mat, protocol.meas_mat, protocol.n_el
    if ex_mat is None or meas_mat is None:
        raise ValueError("give a pyEIT protocol, or ex_mat and meas_mat")
    ex_mat = np.asarray(ex_mat, dtype=np.int64).reshape(-1, 2)
    meas_mat = np.asarray(meas_mat, dtype=np.int64).reshape(-1, 3)
    n_el = int(n_el) if n_el is not None else int(max(ex_mat.max(), meas_mat[:, :2].max())) + 1
    stimulations = np.zeros((len(ex_mat), n_el))
    stimulations[np.arange(len(ex_mat)), ex_mat[:, 0]] += 1.0
    stimulations[np.arange(len(ex_mat)), ex_mat[:, 1]] -= 1.0
    weights = np.zeros((len(meas_mat), n_el))
    weights[np.arange(len(meas_mat)), meas_mat[:, 0]] += 1.0
    weights[np.arange(len(meas_mat)), meas_mat[:, 1]] -= 1.0
    return Protocol.from_arrays(stimulations, weights, meas_mat[:, 2], description="from pyEIT")


def from_pyeit(mesh: Any, protocol: Any) -> tuple[Mesh, Protocol]:
    """A pyEIT mesh and protocol as eitskin's, in one call (point electrodes at ``el_pos``)."""
    return mesh_from_pyeit(mesh), protocol_from_pyeit(protocol)


def plot_elements(mesh: Mesh, values: Any, ax: Any = None, cmap: str = "RdBu", symmetric: bool = True, **kwargs: Any) -> Any:
    """Draws one value per triangle on the mesh with matplotlib's ``tripcolor``, as pyEIT does.

    Parameters
    ----------
    mesh : Mesh
        The mesh the values belong to (its nodes in m).
    values : array_like
        One value per triangle, e.g. ``Reconstructor.element_values`` in S/m.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: the current axes).
    cmap : str
        Colour map; with ``symmetric`` the scale is centred on zero.
    **kwargs
        Passed to ``tripcolor``.

    Returns
    -------
    matplotlib.collections.PolyCollection
    """
    values = np.asarray(values, dtype=float)
    ax = _axes(ax, values, symmetric, kwargs)
    nodes = mesh.nodes
    return ax.tripcolor(nodes[:, 0], nodes[:, 1], mesh.triangles, facecolors=values, cmap=cmap, **kwargs)


def plot_image(image: Image, ax: Any = None, cmap: str = "RdBu", symmetric: bool = True, **kwargs: Any) -> Any:
    """Draws an image with matplotlib, in metres, as pyEIT's examples do.

    Parameters
    ----------
    image : Image
        From ``Reconstructor.image``.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: the current axes).
    cmap : str
        Colour map; with ``symmetric`` the scale is centred on zero.
    **kwargs
        Passed to ``imshow``.

    Returns
    -------
    matplotlib.image.AxesImage
    """
    values = image.values
    ax = _axes(ax, values, symmetric, kwargs)
    return ax.imshow(values, extent=image.extent, origin="upper", cmap=cmap, **kwargs)


def _axes(ax: Any, values: np.ndarray, symmetric: bool, kwargs: dict) -> Any:
    """The axes to draw on (labelled in m, equal aspect), and a colour scale centred on zero
    in ``kwargs`` when ``symmetric``."""
    import matplotlib.pyplot as plt

    ax = ax if ax is not None else plt.gca()
    if symmetric:
        finite = values[np.isfinite(values)]
        peak = float(np.max(np.abs(finite))) if finite.size else 0.0
        kwargs.setdefault("vmin", -(peak or 1.0))
        kwargs.setdefault("vmax", peak or 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return ax
