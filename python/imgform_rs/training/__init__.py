"""Rebuilding the shipped filters and weights from openly licensed images.

Developer tools, run from a checkout; they need the test extras
(``pip install imgform-rs[test]``: scikit-image for its sample images and SciPy).
Nothing here is imported by the rest of the package.
"""
