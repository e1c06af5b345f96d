"""Python's figures speak the CLI's language: the library's one colour map (blue for a
decrease), a colour bar in S/m, the outline, numbered electrodes and ringed touches."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import eitskin  # noqa: E402


def test_the_colour_map_is_the_librarys():
    stops = np.asarray(eitskin.COLOUR_STOPS)
    assert stops.shape == (11, 3)
    cmap = eitskin.colour_map()
    for k, stop in enumerate(stops):
        drawn = np.round(255 * np.asarray(cmap(k / 10)[:3]))
        assert np.all(np.abs(drawn - stop) <= 1), (k, drawn, stop)
    # Blue at the bottom (a decrease, a press), red at the top.
    assert stops[0][2] > stops[0][0] and stops[-1][0] > stops[-1][2]


def test_an_image_is_drawn_with_its_bar_sheet_and_touches():
    spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1000)
    sensor = eitskin.VirtualSensor(spec, seed=2)
    rest = np.array([sensor.frame() for _ in range(10)])
    sensor.press(-0.04, 0.05, 9.0)
    recon = eitskin.Reconstructor.from_reference(spec, rest)
    image = recon.image(recon.reference, sensor.frame())
    touches = eitskin.touches(image)
    fig, ax = plt.subplots()
    drawn = eitskin.plot_image(image, ax=ax, spec=spec, touches=touches)
    assert drawn.get_cmap().name == "eitskin"
    low, high = drawn.get_clim()
    assert low == -high and high == np.nanmax(np.abs(image.values))
    bars = [a for a in fig.axes if a is not ax]
    assert len(bars) == 1 and bars[0].get_ylabel() == "Δσ (S/m)"
    numbers = sorted(int(t.get_text()) for t in ax.texts)
    assert numbers == list(range(1, spec.electrode_count + 1))
    assert ax.get_title() == "Conductivity change"
    # The strongest change is the press, a decrease: its pixel is drawn blue.
    row, column = np.unravel_index(np.nanargmax(np.abs(image.values)), image.values.shape)
    r, g, b, _ = drawn.to_rgba(image.values[row, column])
    assert image.values[row, column] < 0 and b > r
    # The touch is ringed where it is.
    rings = [line for line in ax.lines if line.get_marker() == "o"]
    assert len(rings) == len(touches) >= 1
    assert np.allclose(rings[0].get_xydata()[0], touches[0].centre)
    plt.close(fig)
