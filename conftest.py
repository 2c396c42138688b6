"""Settings for every test, doctests included."""

import numpy as np
import pytest


@pytest.fixture(autouse=True)
def _numpy_print_defaults():
    """colour-science (a test extra) switches NumPy to its 1.13 print style when
    imported; the docstring examples are written in NumPy's current style."""
    with np.printoptions(legacy=False):
        yield
