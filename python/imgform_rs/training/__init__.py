"""Rebuilding the shipped filters and weights from openly licensed images, and the
training images of the learned demosaicers (:func:`imgform_rs.training.sets.training_images`).

Developer tools, run from a checkout; they need the test extras
(``pip install imgform-rs[test]``: scikit-image for its sample images and SciPy).
Nothing here is imported by the rest of the package.
"""
