"""The paper's synthetic protocol (method.md §"Evaluation protocol"), with
ground truth.

Camera: fx = 305.18, fy = 302.45, cx = 511.61, cy = 631.89, 1024 × 1280
(≈ 118° × 129° through a pinhole). Five lenses (``KINDS``), all on normalised
coordinates ``(x, y) = (X/Z, Y/Z)``; ``LENSES`` describes each in a sentence
(it is the truth's ``lens``). The paper's three (``PAPER_KINDS``):

- ``radial``: OpenCV's model, k1 = 0.05, k2 = 0.0267, k3 = 0.0067,
  p1 = 0.0067, p2 = 0.01 (exactly representable by ``--method zhang``);
- ``fisheye``: Kannala–Brandt angle polynomial k1..k4 = 0.05, 0.02, 0.01,
  0.005 on θ = atan r, then OpenCV tangential p1 = p2 = 1e-4;
- ``asymmetric``: the paper leaves it unspecified; ours is a mild radial
  term, quadrant-dependent cubic offsets blended smoothly across the axes,
  and two global sinusoids (``asymmetric_offset`` below): no parametric model
  represents it.

and two more that no textbook model (OpenCV 5/8 coefficients, Kannala–Brandt)
represents either, each smooth, one-to-one and with a positive Jacobian over
the whole half-space in front of the camera (so the Newton inversion of
``render`` and the models' unprojection converge everywhere):

- ``freeform``: a freeform surface with no symmetry: a mild radial term plus
  a vector Zernike-like expansion (different x and y barrel, trefoil,
  quadrafoil, a 5th-order anisotropic term) and a Gaussian bump, all in the
  ray's direction cosines (``freeform_offset``);
- ``decentred``: a decentred, tilted element: radial distortion about a
  centre 0.1 off the principal point, then the keystone of the element's
  tilt, a projective map about that centre (``decentred_distort``).

And one lens past 180° (``WIDE_KINDS``), defined on the angle off the axis
``θ = atan2(√(X² + Y²), Z)`` rather than on the pinhole plane:

- ``fisheye200``: a circular fisheye seeing 100° off its axis all round,
  Kannala–Brandt θd = θ (1 − 0.032 θ² + 0.002 θ⁴) (exactly the ``fisheye``
  method's model): its training views are boards all round the camera, up to
  and past its side (``protocol.py``), and ``render`` draws them.

Their radial terms have OpenCV's positive sign, like the paper's: an
expanding map, which stays one-to-one however far off axis (a negative k1
folds back at r = 1/√(3|k1|), inside this field of view).

Training views see a large 22 × 22 board of 50 mm squares from close by,
filling the frame, from 10 poses tilted every way; corners outside the image are dropped; noise is
Gaussian, σ per axis. Hold-out views are noise-free views of a much larger
board that together cover the whole image, corners included.
"""
from .lenses import (
    ALL_KINDS,
    DECENTRE,
    HOLDOUT_BOARD,
    IMAGE_SIZE,
    INTRINSICS,
    KINDS,
    LENSES,
    PAPER_KINDS,
    SQUARE,
    TILT,
    TRAIN_BOARD,
    TRUTH_FORMAT,
    WIDE_HALF_FIELD_DEG,
    WIDE_KINDS,
    asymmetric_offset,
    decentred_distort,
    direction_cosines,
    freeform_offset,
    in_view,
    opencv_distort,
    true_distort,
    true_project,
    true_rays,
)
from .protocol import SynthSet, board_points, generate, look_at_pose, pose_looking_at, shoot

__all__ = ["ALL_KINDS", "WIDE_HALF_FIELD_DEG", "WIDE_KINDS", "in_view", "true_rays", "DECENTRE", "HOLDOUT_BOARD", "IMAGE_SIZE", "INTRINSICS", "KINDS", "LENSES", "PAPER_KINDS", "SQUARE", "TILT",
           "TRAIN_BOARD", "TRUTH_FORMAT", "SynthSet", "asymmetric_offset", "board_points", "decentred_distort",
           "direction_cosines", "freeform_offset", "generate", "look_at_pose", "pose_looking_at", "shoot", "opencv_distort", "true_distort",
           "true_project"]
