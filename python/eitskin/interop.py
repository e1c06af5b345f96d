"""Interop with pyEIT and matplotlib."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ._eitskin import Image, Mesh


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
    import matplotlib.pyplot as plt

    ax = ax if ax is not None else plt.gca()
    values = image.values
    if symmetric:
        peak = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
        kwargs.setdefault("vmin", -peak)
        kwargs.setdefault("vmax", peak)
    drawn = ax.imshow(values, extent=image.extent, origin="upper", cmap=cmap, **kwargs)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return drawn
