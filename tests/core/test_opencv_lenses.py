"""The benchmark's simulated lenses project as their formulas say."""
import numpy as np
import pytest

from calib_core.synth.opencv_lenses import RANDOM_KINDS, equisolid_lens, random_lens, stereographic_lens, views_of


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


@pytest.mark.parametrize("kind", RANDOM_KINDS)
def test_a_random_lens_maps_each_ray_to_one_pixel_and_is_drawn_again_alike(kind):
    # A drawn polynomial that turns back would put rays from beyond the field of view back
    # inside the image, as no real lens does: along every azimuth the image radius grows with
    # the angle off axis for as long as rays are seen.
    for seed in range(8):
        project, size, _, _ = random_lens(kind, seed)
        theta = np.radians(np.linspace(1.0, 89.0, 400))
        for azimuth in np.radians([0.0, 45.0, 130.0, 250.0]):
            rays = np.column_stack([np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth), np.cos(theta)])
            pixels = project(rays * 500.0)
            seen = np.all(np.isfinite(pixels), axis=1)
            assert seen[: np.argmin(seen) if not seen.all() else len(seen)].all()  # seen up to a last angle
            radius = np.linalg.norm(pixels[seen] - project(np.array([[0.0, 0.0, 500.0]])), axis=1)
            assert np.all(np.diff(radius) > 0), (kind, seed, np.degrees(azimuth))
        again, _, _, _ = random_lens(kind, seed)
        assert np.array_equal(again(rays * 500.0), project(rays * 500.0), equal_nan=True)


def test_views_of_a_random_lens_hold_no_corner_past_its_reach():
    project, size, distance, spread = random_lens("rational", 1)
    obs = views_of(project, size, 6, seed=0, sigma=0.0, distance=distance, spread=spread)
    for view in obs.views:
        assert np.all(np.isfinite(view.image_points))
        assert np.all((view.image_points >= 0) & (view.image_points <= np.array(size) - 1))


@pytest.mark.parametrize("kind", [k for k in RANDOM_KINDS if k != "fisheye"])
def test_a_random_lens_that_is_no_fisheye_images_the_whole_frame(kind):
    # Its rays reach past the frame's border in every direction (a fisheye may image a disc).
    for seed in range(8):
        project, (w, h), _, _ = random_lens(kind, seed)
        theta = np.radians(np.linspace(1.0, 89.0, 800))
        for azimuth in np.radians(np.arange(0.0, 360.0, 15.0)):
            rays = np.column_stack([np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth), np.cos(theta)])
            pixels = project(rays * 500.0)
            last = pixels[np.all(np.isfinite(pixels), axis=1)][-1]
            assert not (0 <= last[0] <= w - 1 and 0 <= last[1] <= h - 1), (kind, seed, np.degrees(azimuth))
