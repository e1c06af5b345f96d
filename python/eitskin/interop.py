"""Interop with pyEIT and matplotlib."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ._eitskin import COLOUR_STOPS, Image, Mesh, Protocol, SensorSpec


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


def colour_map() -> Any:
    """eitskin's one colour map as a matplotlib colormap: ColorBrewer's RdBu reversed
    (``"RdBu_r"``), blue where the conductivity fell (a press), red where it rose, the stops
    the CLI's figures and the live viewer draw with (``eitskin.COLOUR_STOPS``).

    Returns
    -------
    matplotlib.colors.LinearSegmentedColormap
    """
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("eitskin", np.asarray(COLOUR_STOPS, dtype=float) / 255.0, N=1001)


def plot_elements(
    mesh: Mesh, values: Any, ax: Any = None, cmap: Any = None, symmetric: bool = True, **kwargs: Any
) -> Any:
    """Draws one value per triangle on the mesh with matplotlib's ``tripcolor``, as pyEIT does.

    Parameters
    ----------
    mesh : Mesh
        The mesh the values belong to (its nodes in m).
    values : array_like
        One value per triangle, e.g. ``Reconstructor.element_values`` in S/m.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: the current axes).
    cmap : str or Colormap, optional
        Colour map (default: :func:`colour_map`); with ``symmetric`` the scale is centred on zero.
    **kwargs
        Passed to ``tripcolor``.

    Returns
    -------
    matplotlib.collections.PolyCollection
    """
    values = np.asarray(values, dtype=float)
    ax = _axes(ax, values, symmetric, kwargs)
    nodes = mesh.nodes
    return ax.tripcolor(
        nodes[:, 0], nodes[:, 1], mesh.triangles, facecolors=values, cmap=cmap or colour_map(), **kwargs
    )


def plot_image(
    image: Image,
    ax: Any = None,
    spec: SensorSpec | None = None,
    touches: Sequence[Any] = (),
    title: str | None = "Conductivity change",
    cmap: Any = None,
    symmetric: bool = True,
    colorbar: bool = True,
    **kwargs: Any,
) -> Any:
    """Draws an image as ``eitskin image --png`` does: the colour map of the CLI and the viewer
    (blue for a decrease) on a scale symmetric about zero, a colour bar in S/m, and with
    ``spec`` its outline and numbered electrodes; each touch ringed. Lengths in m.

    Parameters
    ----------
    image : Image
        From ``Reconstructor.image``.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: the current axes).
    spec : SensorSpec, optional
        The sensor, for its outline and electrodes.
    touches : sequence of Touch or TouchForce
        Touches to ring (anything with a ``centre`` in m), e.g. ``eitskin.touches(image)``.
    title : str or None
        The axes' title.
    cmap : str or Colormap, optional
        Colour map (default: :func:`colour_map`).
    symmetric : bool
        Centre the scale on zero (±the largest |change|).
    colorbar : bool
        Draw the colour bar, labelled "Δσ (S/m)".
    **kwargs
        Passed to ``imshow``.

    Returns
    -------
    matplotlib.image.AxesImage
    """
    values = image.values
    ax = _axes(ax, values, symmetric, kwargs)
    kwargs.setdefault("interpolation", "nearest")
    drawn = ax.imshow(values, extent=image.extent, origin="upper", cmap=cmap or colour_map(), **kwargs)
    if colorbar:
        ax.figure.colorbar(drawn, ax=ax, label="Δσ (S/m)", shrink=0.85)
    if spec is not None:
        outline = spec.outline
        ax.plot(outline[:, 0], outline[:, 1], color="black", linewidth=1)
        # Room around the outline for the electrodes' numbers, inside the axes.
        low, high = outline.min(axis=0), outline.max(axis=0)
        pad = 0.1 * float(np.max(high - low))
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        electrodes = spec.electrodes
        ax.plot(electrodes[:, 0], electrodes[:, 1], "s", color="black", markersize=4)
        for k, (x, y) in enumerate(electrodes):
            direction = np.array([x, y]) / (np.hypot(x, y) or 1.0)
            ax.annotate(
                str(k + 1), (x, y), xytext=tuple(10 * direction), textcoords="offset points",
                ha="center", va="center", fontsize=7,
            )
    for touch in touches:
        ax.plot(*touch.centre, "o", markersize=14, markerfacecolor="none", markeredgecolor="black", markeredgewidth=2)
    if title:
        ax.set_title(title)
    return drawn


def _axes(ax: Any, values: np.ndarray, symmetric: bool, kwargs: dict) -> Any:
    """The axes to draw on (labelled in m, equal aspect, few enough ticks to stay apart), and a
    colour scale centred on zero in ``kwargs`` when ``symmetric``."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    ax = ax if ax is not None else plt.gca()
    if symmetric:
        finite = values[np.isfinite(values)]
        peak = float(np.max(np.abs(finite))) if finite.size else 0.0
        kwargs.setdefault("vmin", -(peak or 1.0))
        kwargs.setdefault("vmax", peak or 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.xaxis.set_major_locator(MaxNLocator(5))
    ax.yaxis.set_major_locator(MaxNLocator(5))
    return ax
