"""A picture of the humanoid standing on the floor of its ``scene.xml``: the image in its README.

The robot is rendered offscreen (``mujoco.Renderer``; headless through ``MUJOCO_GL``, which the
``sim`` package sets) in the model's reference pose: straight legs, arms hanging, head level,
soles on the floor. A free camera looks at it from its front right, slightly from above; the
picture is 300 x 400 pixels.

Run ``python -m sim.world.render_robot`` to regenerate ``robot_models/humanoid/humanoid.png``;
``--out``, ``--width`` and ``--height`` choose another file and size.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import mujoco
import numpy as np

from robot_models import HUMANOID_DIR, humanoid_path
from sim.atomic import atomic_path
from sim.command_line import OneLineParser, integer_option, path_option, script_status

#: Where the README expects the picture.
DEFAULT_PICTURE_PATH = HUMANOID_DIR / "humanoid.png"
#: The largest side of the picture, pixels (the offscreen buffer's default size).
MAX_SIDE_PX = 2048


def render_humanoid(width: int = 300, height: int = 400, azimuth_deg: float = 135.0,
                    elevation_deg: float = -15.0, distance_m: float = 1.05) -> np.ndarray:
    """Render the robot standing in ``scene.xml``.

    Parameters
    ----------
    width, height : int, optional
        Image size in pixels (at most ``MAX_SIDE_PX`` each).
    azimuth_deg : float, optional
        Camera direction around the vertical, degrees (MuJoCo's free-camera azimuth; 180
        looks straight at the robot's front, which faces +x).
    elevation_deg : float, optional
        Camera elevation, degrees; negative looks down.
    distance_m : float, optional
        Distance from the camera to the look-at point, half-way up the robot.

    Returns
    -------
    image : (height, width, 3) uint8 ndarray
        The RGB picture.
    """
    if not (0 < width <= MAX_SIDE_PX and 0 < height <= MAX_SIDE_PX):
        raise ValueError(f"width and height must be in 1..{MAX_SIDE_PX} pixels, got {width} x "
                         f"{height}")
    if distance_m <= 0:
        raise ValueError(f"distance_m must be > 0, got {distance_m!r}")
    model = mujoco.MjModel.from_xml_path(str(humanoid_path("scene.xml")))
    # The offscreen buffer must hold the picture (MuJoCo's default is 640 x 480).
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    # A brighter headlight than the scene's own, so the dark grey limbs stand apart.
    model.vis.headlight.diffuse[:] = 0.9
    model.vis.headlight.ambient[:] = 0.45
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)                # reference pose: the soles rest on z = 0
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = (0.0, 0.0, 0.31)
    camera.azimuth = azimuth_deg
    camera.elevation = elevation_deg
    camera.distance = distance_m
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.update_scene(data, camera=camera)
        return renderer.render().copy()


def save_png(image: np.ndarray, path: Path) -> Path:
    """Write an RGB image as a maximally compressed PNG, atomically (an interrupted write
    leaves the previous picture); returns the path."""
    path = Path(path)
    encoded, png = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not encoded:
        raise OSError(f"could not encode {path} as PNG")
    with atomic_path(path) as temporary:
        temporary.write_bytes(png.tobytes())
    return path


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m sim.world.render_robot",
                           description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=path_option, default=DEFAULT_PICTURE_PATH,
                        help="PNG to write")
    parser.add_argument("--width", type=integer_option(1, MAX_SIDE_PX), default=300,
                        help="pixels")
    parser.add_argument("--height", type=integer_option(1, MAX_SIDE_PX), default=400,
                        help="pixels")
    args = parser.parse_args(argv)
    if args.out.suffix.lower() != ".png" or not args.out.parent.is_dir():
        parser.error(f"--out {args.out}: accepted: a .png file in an existing folder")
    image = render_humanoid(args.width, args.height)
    try:
        path = save_png(image, args.out)
    except OSError as error:
        parser.error(f"--out {args.out}: {error}; accepted: a writable .png path")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(script_status(main))
