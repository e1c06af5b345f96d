"""What the tests share: where the reference data are.

`$EITSKIN_SHARED`, else `../shared` beside the checkout, as the Rust tests find it
(crates/eitskin-testdata). A test whose data are missing fails and says where it looked: a
comparison not made is never a pass.
"""

import os
import pathlib

import pytest

CHECKOUT = pathlib.Path(__file__).resolve().parents[2]


def shared(*parts):
    """The path `parts` under the shared folder; fails the test when it is not there."""
    root = pathlib.Path(os.environ.get("EITSKIN_SHARED") or CHECKOUT / ".." / "shared")
    path = root.joinpath(*parts)
    if not path.exists():
        pytest.fail(
            f"{path} is missing: the reference data live in ../shared beside the checkout, or set EITSKIN_SHARED",
            pytrace=False,
        )
    return path
