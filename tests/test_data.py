"""The motorcycle pair read from scikit-image's data folder is what scikit-image returns."""
import numpy as np

from sim.scenes.data import motorcycle


def test_motorcycle_is_skimages():
    from skimage import data
    for ours, theirs in zip(motorcycle(), data.stereo_motorcycle()):
        assert ours.dtype == theirs.dtype and np.array_equal(ours, theirs)
