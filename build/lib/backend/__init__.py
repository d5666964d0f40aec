"""freecal's service and command line (the calibration itself is calib_core).

OpenCV reads its decoding limit, ``OPENCV_IO_MAX_IMAGE_PIXELS``, once: when cv2
loads, which is on the first import of calib_core. So it is set here, before
anything of freecal imports cv2, from the service's own limit: no freecal
process (the API, a worker, a job, a command) decodes an image larger than
``FREECAL_MAX_IMAGE_PIXELS``, whatever its header claimed.
"""
import os

from .base.settings import Settings

_limit = os.environ.get("FREECAL_MAX_IMAGE_PIXELS", "").strip()
if _limit.isdigit():  # the service's limit is OpenCV's, whatever a parent process left in the environment
    os.environ["OPENCV_IO_MAX_IMAGE_PIXELS"] = _limit
else:  # unset (the default), or malformed: refused later, in words (Settings.from_env); OpenCV would abort on it
    os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(Settings.max_image_pixels))
