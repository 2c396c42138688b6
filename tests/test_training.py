"""The training sets of the learned demosaicers hold no evaluation image."""

from __future__ import annotations

import csv

import pytest

from conftest import shared_path
from imgform_rs.training import demosaic as raisr_training
from imgform_rs.training import leung2011, photos


def test_no_scikit_image_evaluation_image_is_trained_on():
    trained = {*raisr_training.SKIMAGE_GREY, *raisr_training.SKIMAGE_RGB, *leung2011.GREY}
    assert not trained & raisr_training.HELD_OUT
    # leung2011 also trains on the Hubble deep field, which no benchmark scores.
    assert "hubble_deep_field" not in raisr_training.EVALUATION_IMAGES


def test_no_validation_image_is_among_the_training_photographs():
    manifest = shared_path("data/demosaic-val/MANIFEST.tsv")
    if manifest is None:
        pytest.skip("../shared/data/demosaic-val is absent")
    with manifest.open(newline="") as f:
        digests = [row["sha256"] for row in csv.DictReader(f, delimiter="\t")]
    assert len(digests) == 92
    for photo in [*photos.TRAINING, *photos.HELD_OUT]:
        assert len(photo.sha256) == 16
        clashes = [d for d in digests if d.startswith(photo.sha256)]
        assert not clashes, f"{photo.name} is a validation image"
