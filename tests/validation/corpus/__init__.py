"""The realistic evaluation corpus: Mitsuba 3 scenes turned into Matterport-layout scans with ground truth.

- `generate`: procedural interiors (rooms, houses) written as Mitsuba XML with PNG textures and EXR skies.
- `convert`: a loaded Mitsuba scene as scan objects (triangles in the z-up scan frame, Disney materials,
  emission) and the per-pixel ground truth (object ids, base colour) of pixel-centre rays.
- `cameras`: Matterport-like capture (tripod positions in free space, 3 tilts × 6 yaws) and `.conf` files.
- `scan`: the whole build of one scene: layout files, photos, held-out views, ground truth.
- `score`: compares a finished pipeline run with a scan's ground truth.
- `scenes`: the named scenes of `scripts/corpus build`.

Everything runs on Mitsuba's `llvm_ad_rgb` variant with a chosen thread count (one by default), seeded.
"""
