"""Mitsuba 3 baseline of the per-object inverse-rendering fit: the reference our speed is compared to.

- `scene`: a Matterport-layout scan (house_segmentations/, undistorted_camera_parameters/*.conf,
  undistorted_color_images/*.exr) as a Mitsuba scene — one mesh per object with a two-sided `diffuse` BSDF and
  an `area` emitter, one `perspective` sensor per view, matching our renderer's conventions exactly (see its
  module docstring); `read_truth` reads ground_truth_materials.json (ipt-materials/1).
- `solve`: `python -m mitsuba_baseline.solve --scene DIR --budget-seconds S --out results.csv` (run from
  tests/validation with deps/venv/bin/python): `prb` + llvm_ad_rgb + `mi.ad.Adam` on every object's
  reflectance and emission radiance, L1 loss on the photos, writing accuracy against wall time.

Checked by tests/validation/test_mitsuba_baseline.py.
"""
