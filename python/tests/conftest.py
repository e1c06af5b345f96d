"""What the tests share: where the reference results are.

The EIDORS and pyEIT results live in the repository (`testdata/reference/`, with READMEs that
state their conventions and provenance), as the Rust tests find them (crates/eitskin-testdata).
"""

import pathlib

CHECKOUT = pathlib.Path(__file__).resolve().parents[2]


def reference(*parts):
    """The path `parts` under the repository's `testdata/reference`."""
    return CHECKOUT.joinpath("testdata", "reference", *parts)
