"""The benchmark's simulated lenses project as their formulas say."""
import numpy as np

from calib_core.synth.opencv_lenses import equisolid_lens, stereographic_lens


def test_the_fisheye_projections_put_a_ray_at_their_radius():
    """60° off axis, in any azimuth: r = 2f sin 30° = f (equisolid), 2f tan 30° (stereographic)."""
    azimuth = np.radians([0.0, 90.0, 215.0])
    theta = np.radians(60.0)
    rays = np.column_stack([np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth),
                            np.full(3, np.cos(theta))]) * 500.0
    for project, radius in ((equisolid_lens, 380.0), (stereographic_lens, 600.0 * np.tan(np.radians(30.0)))):
        offset = project(rays) - [640.0, 512.0]
        assert np.allclose(np.hypot(offset[:, 0], offset[:, 1]), radius)
        assert np.allclose(np.arctan2(offset[:, 1], offset[:, 0]) % (2 * np.pi), azimuth)
