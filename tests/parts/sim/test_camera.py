from __future__ import annotations

import math

import numpy as np
import pytest

from parts.sim.camera import PinholeCamera
from parts.sim.image_sensor import ImageSensor
from parts.sim.world import load_world


@pytest.fixture
def track_and_texture(world):
    w = load_world(2, **world)
    return w.track, w.texture


def ground_to_pixel(cam: PinholeCamera, x_car: float, y_car: float) -> tuple[float, float]:
    """Project a ground point given in the car frame to image pixels (inverse homography)."""
    p = np.linalg.inv(cam.car_from_pixel) @ np.array([x_car, y_car, 1.0])
    return p[0] / p[2], p[1] / p[2]


def test_homography_matches_pinhole_geometry():
    cam = PinholeCamera(160, 120, fov_deg=90.0, pitch_deg=30.0, height_m=0.2, forward_m=0.1)
    # the optical axis hits the ground at h / tan(pitch) ahead of the camera, in the image centre
    u, v = ground_to_pixel(cam, 0.1 + 0.2 / math.tan(math.radians(30)), 0.0)
    assert (u, v) == pytest.approx((79.5, 59.5), abs=1e-6)
    # a point to the left of the car appears left of centre, further points appear higher up
    assert ground_to_pixel(cam, 1.0, 0.3)[0] < 79.5
    assert ground_to_pixel(cam, 2.0, 0.0)[1] < ground_to_pixel(cam, 1.0, 0.0)[1]
    # horizontal field of view: the camera ray (1, 0, 1) (45 deg right) meets the right image edge
    t = 0.2 / math.sin(math.radians(30))
    u, v = ground_to_pixel(cam, 0.1 + t * math.cos(math.radians(30)), -t)
    assert (u, v) == pytest.approx((159.5, 59.5), abs=1e-6)


def test_render_sees_the_road_ahead_and_the_sky(track_and_texture):
    track, tex = track_and_texture
    cam = PinholeCamera(160, 120)
    x, y, h = track.pose_at(3.0, -0.2)  # right half of the road: asphalt under the camera
    img = cam.render(tex, x, y, h)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    assert 0 < cam.ground_row < 60
    sky = img[: cam.ground_row // 2]
    assert sky[..., 2].mean() > sky[..., 0].mean()  # blue-ish sky at the top
    # the road (grey, low saturation) fills the bottom centre; the verge differs from it
    bottom = img[-10:, 70:90].astype(float)
    assert np.abs(bottom[..., 0] - bottom[..., 1]).mean() < 25
    # moving the car sideways by half a road width moves the road in the image
    img2 = cam.render(tex, x + 0.4 * math.sin(h), y - 0.4 * math.cos(h), h)
    assert np.abs(img.astype(int) - img2.astype(int)).mean() > 10


def test_other_resolutions_and_buffers(track_and_texture):
    track, tex = track_and_texture
    cam = PinholeCamera(320, 160, fov_deg=80.0)
    out = np.zeros((160, 320, 3), np.uint8)
    res = cam.render(tex, *track.pose_at(0.0), out=out)
    assert res is out and out.any()


def test_camera_rejects_bad_settings():
    with pytest.raises(ValueError, match="fov"):
        PinholeCamera(fov_deg=200)
    with pytest.raises(ValueError, match="size"):
        PinholeCamera(4, 4)
    with pytest.raises(ValueError, match="height"):
        PinholeCamera(height_m=0)


def test_sensor_effects_are_seeded_and_change_images():
    img = np.full((20, 30, 3), 100, np.uint8)
    assert not ImageSensor(30, 20).active
    a = ImageSensor(30, 20, noise=5.0, brightness=0.3, seed=1).apply(img.copy())
    b = ImageSensor(30, 20, noise=5.0, brightness=0.3, seed=1).apply(img.copy())
    c = ImageSensor(30, 20, noise=5.0, brightness=0.3, seed=2).apply(img.copy())
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert 3.0 < (a.astype(float) - a.mean()).std() < 7.0  # per-pixel noise of about 5
    edge = np.zeros((20, 30, 3), np.uint8)
    edge[:, 15:] = 200
    blurred = ImageSensor(30, 20, blur=5).apply(edge.copy())
    assert 0 < blurred[10, 14, 0] < 200
    with pytest.raises(ValueError, match="jitter"):
        ImageSensor(30, 20, brightness=1.5)


def test_lens_distortion_bends_the_pinhole_image_as_opencvs_model(track_and_texture):
    import cv2

    track, tex = track_and_texture
    dist = (-0.25, 0.07, 0.001, -0.0015, 0.0)
    pinhole, lens = PinholeCamera(320, 240), PinholeCamera(320, 240, distortion=dist)
    assert not pinhole.distorted and lens.distorted
    assert lens.canvas_size[0] > 320 and lens.canvas_size[1] > 240  # barrel: the lens sees wider
    pose = track.pose_at(2.0, -0.2)
    a, b = pinhole.render(tex, *pose), lens.render(tex, *pose)
    assert b.shape == a.shape and np.abs(a.astype(int) - b.astype(int)).mean() > 5
    # a ground point seen by the pinhole at pixel p is seen through the lens where OpenCV's model
    # distorts p to (the lens image is the pinhole image bent by cv2.projectPoints' mapping)
    ground = np.array([[0.6, 0.15], [1.0, -0.3], [0.45, 0.25]])
    p_pin, p_lens = pinhole.project_ground(ground), lens.project_ground(ground)
    k = pinhole.intrinsics
    rays = np.column_stack([(p_pin - k[:2, 2]) / k[0, 0], np.ones(3)])
    expected, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, np.array(dist))
    assert np.allclose(p_lens, expected.reshape(-1, 2), atol=1e-6)
    # and the rendered images agree there (bilinear sampling: a few grey levels)
    for (u0, v0), (u1, v1) in zip(p_pin, p_lens, strict=True):
        pa = a[int(round(v0)), int(round(u0))].astype(int)
        pb = b[int(round(v1)), int(round(u1))].astype(int)
        assert np.abs(pa - pb).max() < 40
    assert PinholeCamera(160, 120, distortion=(0, 0, 0, 0, 0)).distortion is None  # all zero = a pinhole
    with pytest.raises(ValueError, match="cannot be inverted"):
        PinholeCamera(320, 240, distortion=(-0.1, 0.0, 0.0, 0.0, 0.0))  # folds before the image corners
    with pytest.raises(ValueError, match="4, 5 or 8"):
        PinholeCamera(distortion=(0.1, 0.2))


def test_lane_region_points_make_a_true_birds_eye_view():
    import cv2

    from parts.sim.camera import lane_region_points

    cam = PinholeCamera(160, 120)
    pts = lane_region_points(cam, near=0.4, far=1.2, half_width=0.5)
    assert pts["LANE_POINTS_SIZE"] == [160, 120]
    src = np.float32(pts["LANE_SOURCE_POINTS"])
    dst = np.float32(pts["LANE_DESTINATION_POINTS"])
    m = cv2.getPerspectiveTransform(src, dst)
    # two parallel lines on the ground (0.2 m either side) stay parallel and equally apart in the warp
    along = np.linspace(0.45, 1.15, 6)
    for y in (0.2, -0.2):
        line = cam.project_ground(np.column_stack([along, np.full(6, y)]))
        warped = cv2.perspectiveTransform(line.reshape(-1, 1, 2).astype(np.float32), m).reshape(-1, 2)
        assert np.ptp(warped[:, 0]) < 0.05  # vertical in the bird's-eye view
        assert warped[0, 0] == pytest.approx(77.5 - y / 0.5 * 37.5, abs=0.05)
    with pytest.raises(ValueError, match="near < far"):
        lane_region_points(cam, near=2.0, far=1.0)


def test_lane_region_points_of_an_undistorting_car_make_a_true_birds_eye_view_of_its_frames():
    """With a wide-angle lens and CAMERA_UNDISTORT the pilot sees undistorted frames: the points
    must be computed in those (camera matrix ``intrinsics``), not in the frames as the lens bends them."""
    import cv2

    from parts.sim.camera import lane_region_points
    from parts.vision.calibration import CameraCalibration
    from parts.vision.undistort import Undistort

    dist = np.array([-0.25, 0.07, 0.001, -0.0015, 0.0])
    cam = PinholeCamera(320, 240, distortion=dist)
    new_k = Undistort(CameraCalibration((320, 240), cam.intrinsics, dist, 0.1)).output_camera_matrix(320, 240)
    along = np.linspace(0.45, 1.15, 6)

    def spread(points):
        """Largest horizontal spread of the two ground lines (0.2 m either side) in the warp of the
        undistorted frame: 0 for a true bird's-eye view."""
        m = cv2.getPerspectiveTransform(np.float32(points["LANE_SOURCE_POINTS"]),
                                        np.float32(points["LANE_DESTINATION_POINTS"]))
        worst = 0.0
        for y in (0.2, -0.2):
            bent = cam.project_ground(np.column_stack([along, np.full(6, y)]))  # as the lens shows them
            seen = cv2.undistortPoints(bent.reshape(-1, 1, 2), cam.intrinsics, dist, P=new_k)  # undistorted
            warped = cv2.perspectiveTransform(seen.astype(np.float32), m).reshape(-1, 2)
            worst = max(worst, float(np.ptp(warped[:, 0])))
        return worst

    right = lane_region_points(cam, near=0.4, far=1.2, half_width=0.5, intrinsics=new_k)
    assert spread(right) < 0.05
    assert spread(lane_region_points(cam, near=0.4, far=1.2, half_width=0.5)) > 1.0  # the lens's points: bent
    # the default near edge is the nearest ground the undistorted frame shows (inside it)
    auto = lane_region_points(cam, intrinsics=new_k)
    bottom_y = max(p[1] for p in auto["LANE_SOURCE_POINTS"])
    assert 200 < bottom_y < 239
