"""The validation suite's own tools work: open3d, pycolmap and Mitsuba 3 (llvm_ad_rgb) import and run."""
import numpy as np


def test_open3d_builds_a_mesh():
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh.create_box(1.0, 2.0, 3.0)
    assert len(mesh.triangles) == 12
    assert abs(mesh.get_surface_area() - 2 * (2 + 3 + 6)) < 1e-9


def test_pycolmap_projects_a_point():
    import pycolmap

    cam = pycolmap.Camera(model="PINHOLE", width=100, height=80, params=[50.0, 60.0, 50.0, 40.0])
    uv = cam.img_from_cam(np.array([[0.1, -0.2, 1.0]]))
    assert np.allclose(uv, [[50.0 + 5.0, 40.0 - 12.0]], atol=1e-9)


def test_mitsuba_renders_a_tiny_image():
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 3},
            "sensor": {
                "type": "perspective",
                "fov": 45,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": 16, "height": 16},
                "sampler": {"type": "independent", "sample_count": 16},
            },
            "emitter": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            "ball": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}}},
        }
    )
    img = np.array(mi.render(scene, seed=1))
    assert img.shape == (16, 16, 3)
    assert np.isfinite(img).all()
    # Corners see the unit environment; the centre sees a white-furnace sphere of albedo 0.5 (radiance 0.5
    # at depth 2, rising towards 1/(1-0.5) only with more bounces, which the sphere cannot give itself).
    assert abs(img[0, 0].mean() - 1.0) < 1e-3
    assert 0.4 < img[8, 8].mean() < 0.6
