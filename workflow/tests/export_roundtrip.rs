//! Export files read back: PLY through ingest's reader (face count, albedo, ids), OBJ/MTL through tobj with
//! the atlas sampled bilinearly at each triangle's centroid UV (PNG within 1/255 of the sRGB albedo, EXR
//! exact), and the GLB's structure (chunks, alignment, buffer views and accessors in bounds, min/max exact,
//! materials, embedded images).

use std::path::Path;

use glam::{Vec2, Vec3};
use ingest::srgb;
use serde_json::Value;
use tracer::Material;
use workflow::export::{self, ExportInput, ExportOptions};

/// SplitMix64 for reproducible fixture values.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

struct Fixture {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    materials: Vec<Material>,
    emission: Vec<Vec3>,
    segment_id: Vec<i32>,
}

impl Fixture {
    /// A `nx × ny` grid of quads in the z = 0 plane (2 triangles each), segments by column bands (ids chosen
    /// non-contiguous and negative to catch id handling), random albedo/roughness/metallic, one emitting
    /// segment with radiance above 1.
    fn grid(nx: u32, ny: u32, seed: u64) -> Self {
        let mut rng = Rng(seed);
        let positions: Vec<Vec3> =
            (0..=ny).flat_map(|j| (0..=nx).map(move |i| Vec3::new(i as f32 * 0.5, j as f32 * 0.25, 0.0))).collect();
        let mut triangles = Vec::new();
        let mut segment_id = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let v = |di: u32, dj: u32| (j + dj) * (nx + 1) + i + di;
                triangles.push([v(0, 0), v(1, 0), v(1, 1)]);
                triangles.push([v(0, 0), v(1, 1), v(0, 1)]);
                let seg = [7, -2, 30, 4][(i * 4 / nx) as usize];
                segment_id.extend([seg, seg]);
            }
        }
        let materials = (0..triangles.len())
            .map(|_| Material {
                base_color: Vec3::new(rng.unit(), rng.unit(), rng.unit()),
                roughness: rng.unit(),
                metallic: rng.unit(),
                specular: rng.unit(),
            })
            .collect();
        let emission = segment_id.iter().map(|&s| if s == 4 { Vec3::new(6.0, 3.0, 1.5) } else { Vec3::ZERO }).collect();
        Self { positions, triangles, materials, emission, segment_id }
    }

    fn input(&self) -> ExportInput<'_> {
        ExportInput {
            positions: &self.positions,
            triangles: &self.triangles,
            materials: &self.materials,
            emission: &self.emission,
            segment_id: &self.segment_id,
            detail: None,
        }
    }
}

/// Bilinear sample (texel centres at half-integers, clamp to edge) of an interleaved image at glTF UV
/// (v down from the first row).
fn bilinear(data: &[f32], w: usize, h: usize, channels: usize, uv: Vec2) -> Vec<f32> {
    let x = (uv.x * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
    let y = (uv.y * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let at = |x: usize, y: usize, c: usize| data[(y * w + x) * channels + c];
    (0..channels)
        .map(|c| {
            let top = at(x0, y0, c) * (1.0 - fx) + at(x1, y0, c) * fx;
            let bottom = at(x0, y1, c) * (1.0 - fx) + at(x1, y1, c) * fx;
            top * (1.0 - fy) + bottom * fy
        })
        .collect()
}

fn read_png(path: &Path) -> (Vec<f32>, usize, usize) {
    let img = image::open(path).unwrap().to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    (img.into_raw().into_iter().map(f32::from).collect(), w, h)
}

fn read_exr(path: &Path) -> (Vec<f32>, usize, usize) {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (vec![0f32; 3 * res.width() * res.height()], res.width()),
        |(px, w): &mut (Vec<f32>, usize), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = 3 * (pos.y() * *w + pos.x());
            px[i..i + 3].copy_from_slice(&[r, g, b]);
        },
    )
    .unwrap();
    let size = img.layer_data.size;
    (img.layer_data.channel_data.pixels.0, size.width(), size.height())
}

#[test]
fn ply_reads_back_identically() {
    let fx = Fixture::grid(8, 5, 1);
    let dir = tempfile::tempdir().unwrap();
    export::write_all(dir.path(), &fx.input(), &ExportOptions::default()).unwrap();
    let read = ingest::ply::read_ply(&dir.path().join(export::PLY_FILE)).unwrap();
    let m = &read.mesh;
    assert_eq!(read.face_count, fx.triangles.len());
    assert_eq!(m.triangles, fx.triangles);
    assert_eq!(m.positions, fx.positions);
    assert_eq!(m.face_ids("segment_id").unwrap(), fx.segment_id);
    let col = |name: &str| match m.face_prop(name).unwrap() {
        ingest::ply::FaceValues::F32(v) => v.clone(),
        other => panic!("{name} is not float: {other:?}"),
    };
    for (c, name) in ["albedo_r", "albedo_g", "albedo_b"].iter().enumerate() {
        let expect: Vec<f32> = fx.materials.iter().map(|m| m.base_color[c]).collect();
        assert_eq!(col(name), expect, "{name}");
    }
    assert_eq!(col("roughness"), fx.materials.iter().map(|m| m.roughness).collect::<Vec<_>>());
    assert_eq!(col("metallic"), fx.materials.iter().map(|m| m.metallic).collect::<Vec<_>>());
    assert_eq!(col("emission_r"), fx.emission.iter().map(|e| e.x).collect::<Vec<_>>());
    let red = m.face_ids("red").unwrap();
    for (t, mat) in fx.materials.iter().enumerate() {
        assert_eq!(red[t], i32::from(srgb::linear_to_srgb8(mat.base_color.x)));
    }
    // Column order is the documented one.
    let names: Vec<&str> = m.face_props.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, export::ply::FACE_COLUMNS);
}

#[test]
fn obj_and_atlas_give_each_triangle_its_albedo() {
    let fx = Fixture::grid(9, 7, 2);
    let dir = tempfile::tempdir().unwrap();
    let report = export::write_all(dir.path(), &fx.input(), &ExportOptions::default()).unwrap();
    let (png, w, h) = read_png(&dir.path().join(export::ALBEDO_PNG_FILE));
    let (exr, we, he) = read_exr(&dir.path().join(export::ALBEDO_EXR_FILE));
    assert_eq!((w as u32, h as u32), (report.atlas.width, report.atlas.height));
    assert_eq!((we, he), (w, h));
    assert!(w.is_power_of_two() && h.is_power_of_two());

    let (models, materials) = tobj::load_obj(
        dir.path().join(export::OBJ_FILE),
        &tobj::LoadOptions { single_index: false, triangulate: false, ..Default::default() },
    )
    .unwrap();
    let materials = materials.unwrap();
    assert_eq!(materials.len(), 4, "one material per segment");
    for m in &materials {
        assert_eq!(m.diffuse_texture.as_deref(), Some(export::ALBEDO_PNG_FILE));
    }
    let emitter = materials.iter().find(|m| m.name == "segment_4").unwrap();
    assert_eq!(emitter.emissive, Some([6.0, 3.0, 1.5]));
    assert_eq!(emitter.diffuse, Some([1.0; 3]));
    let mut seen = vec![false; fx.triangles.len()];
    for model in &models {
        let mesh = &model.mesh;
        let seg: i32 = model.name.strip_prefix("segment_").unwrap().parse().unwrap();
        assert_eq!(materials[mesh.material_id.unwrap()].name, model.name);
        for (f, corners) in mesh.indices.chunks_exact(3).enumerate() {
            let tc = &mesh.texcoord_indices[3 * f..3 * f + 3];
            // tobj re-indexes per model, so find the input triangle by its corner positions (unique, in order).
            let p: Vec<Vec3> =
                corners.iter().map(|&i| Vec3::from_slice(&mesh.positions[3 * i as usize..][..3])).collect();
            let t = fx
                .triangles
                .iter()
                .position(|tri| (0..3).all(|c| fx.positions[tri[c] as usize] == p[c]))
                .expect("OBJ face is an input triangle");
            assert!(!seen[t]);
            seen[t] = true;
            assert_eq!(seg, fx.segment_id[t]);
            let uv = (0..3)
                .map(|k| {
                    let i = tc[k] as usize;
                    // OBJ v is up; the image's first row is v = 1.
                    Vec2::new(mesh.texcoords[2 * i], 1.0 - mesh.texcoords[2 * i + 1])
                })
                .sum::<Vec2>()
                / 3.0;
            let albedo = fx.materials[t].base_color;
            let s = bilinear(&png, w, h, 3, uv);
            let e = bilinear(&exr, w, h, 3, uv);
            for c in 0..3 {
                assert!(
                    (s[c] / 255.0 - srgb::encode(albedo[c])).abs() <= 1.0 / 255.0,
                    "triangle {t} channel {c}: png {} vs {}",
                    s[c],
                    srgb::encode(albedo[c]) * 255.0
                );
                // Bilinear weights sum to 1 only up to rounding; the texel under the centroid is exact.
                assert!((e[c] - albedo[c]).abs() <= 1e-6, "triangle {t} channel {c}: exr {} vs {}", e[c], albedo[c]);
                let (x, y) = ((uv.x * w as f32) as usize, (uv.y * h as f32) as usize);
                assert_eq!(exr[3 * (y * w + x) + c], albedo[c], "triangle {t} channel {c}: exr texel");
            }
        }
    }
    assert!(seen.iter().all(|&s| s), "every triangle appears once in the OBJ");
}

/// Parses a GLB, checking the container rules; returns (JSON, BIN).
fn parse_glb(bytes: &[u8]) -> (Value, Vec<u8>) {
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[0..4], b"glTF");
    assert_eq!(u32_at(4), 2);
    assert_eq!(u32_at(8), bytes.len());
    let json_len = u32_at(12);
    assert_eq!(&bytes[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let b = 20 + json_len;
    let bin_len = u32_at(b);
    assert_eq!(&bytes[b + 4..b + 8], b"BIN\0");
    assert_eq!(bin_len % 4, 0);
    assert_eq!(b + 8 + bin_len, bytes.len());
    (json, bytes[b + 8..].to_vec())
}

#[test]
fn glb_structure_is_valid_and_carries_the_materials() {
    let fx = Fixture::grid(6, 4, 3);
    let dir = tempfile::tempdir().unwrap();
    let opts = ExportOptions { z_up: true, ..ExportOptions::default() };
    let report = export::write_all(dir.path(), &fx.input(), &opts).unwrap();
    let (doc, bin) = parse_glb(&std::fs::read(dir.path().join(export::GLB_FILE)).unwrap());
    assert_eq!(doc["asset"]["version"], "2.0");
    assert_eq!(doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize, bin.len());
    assert_eq!(doc["extensionsUsed"], serde_json::json!(["KHR_materials_emissive_strength"]));

    let views = doc["bufferViews"].as_array().unwrap();
    for v in views {
        let (off, len) = (v["byteOffset"].as_u64().unwrap() as usize, v["byteLength"].as_u64().unwrap() as usize);
        assert_eq!(off % 4, 0);
        assert!(off + len <= bin.len());
    }
    let view_bytes = |i: usize| {
        let v = &views[i];
        let off = v["byteOffset"].as_u64().unwrap() as usize;
        &bin[off..off + v["byteLength"].as_u64().unwrap() as usize]
    };
    let floats = |a: &Value| -> Vec<f32> {
        let v = &views[a["bufferView"].as_u64().unwrap() as usize];
        let stride = v["byteStride"].as_u64().unwrap() as usize;
        let width = if a["type"] == "VEC3" { 3 } else { 2 };
        assert_eq!(stride, 4 * width, "tightly packed");
        let off = a["byteOffset"].as_u64().unwrap() as usize;
        let count = a["count"].as_u64().unwrap() as usize;
        assert_eq!(off % 4, 0);
        assert!(off + stride * (count - 1) + 4 * width <= v["byteLength"].as_u64().unwrap() as usize);
        let data = view_bytes(a["bufferView"].as_u64().unwrap() as usize);
        (0..count * width).map(|k| f32::from_le_bytes(data[off + 4 * k..off + 4 * k + 4].try_into().unwrap())).collect()
    };

    // Embedded images decode to the atlas size; the albedo image is the same bytes as albedo.png.
    let images = doc["images"].as_array().unwrap();
    assert_eq!(images.len(), 2);
    let albedo_png = view_bytes(images[0]["bufferView"].as_u64().unwrap() as usize);
    assert_eq!(albedo_png, std::fs::read(dir.path().join(export::ALBEDO_PNG_FILE)).unwrap());
    let mr_png = view_bytes(images[1]["bufferView"].as_u64().unwrap() as usize);
    let mr = image::load_from_memory(mr_png).unwrap().to_rgb8();
    assert_eq!((mr.width(), mr.height()), (report.atlas.width, report.atlas.height));
    let mr: Vec<f32> = mr.into_raw().into_iter().map(f32::from).collect();
    let (albedo, w, h) = read_png(&dir.path().join(export::ALBEDO_PNG_FILE));

    let accessors = doc["accessors"].as_array().unwrap();
    let materials = doc["materials"].as_array().unwrap();
    let mut total_corners = 0;
    let mut emissive = 0;
    for mesh in doc["meshes"].as_array().unwrap() {
        let seg: i32 = mesh["name"].as_str().unwrap().strip_prefix("segment_").unwrap().parse().unwrap();
        for prim in mesh["primitives"].as_array().unwrap() {
            assert_eq!(prim["mode"], 4);
            let pa = &accessors[prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
            let ta = &accessors[prim["attributes"]["TEXCOORD_0"].as_u64().unwrap() as usize];
            let count = pa["count"].as_u64().unwrap() as usize;
            assert_eq!(count % 3, 0);
            assert_eq!(ta["count"], pa["count"]);
            let pos = floats(pa);
            let uvs = floats(ta);
            // min/max are exactly the data's bounds (the validator's ACCESSOR_MIN_MISMATCH rule).
            for c in 0..3 {
                let vals = pos.iter().skip(c).step_by(3);
                let lo = vals.clone().copied().fold(f32::INFINITY, f32::min);
                let hi = vals.copied().fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(pa["min"][c].as_f64().unwrap() as f32, lo);
                assert_eq!(pa["max"][c].as_f64().unwrap() as f32, hi);
            }
            let mat = &materials[prim["material"].as_u64().unwrap() as usize];
            let pbr = &mat["pbrMetallicRoughness"];
            assert_eq!(pbr["baseColorTexture"]["index"], 0);
            assert_eq!(pbr["metallicRoughnessTexture"]["index"], 1);
            // Each triangle: find it by its corner positions, sample both textures at the centroid UV.
            for k in 0..count / 3 {
                let p: Vec<Vec3> = (0..3).map(|c| Vec3::from_slice(&pos[9 * k + 3 * c..9 * k + 3 * c + 3])).collect();
                let t = fx
                    .triangles
                    .iter()
                    .position(|tri| (0..3).all(|c| fx.positions[tri[c] as usize] == p[c]))
                    .expect("primitive triangle is an input triangle");
                assert_eq!(fx.segment_id[t], seg);
                let uv = (0..3).map(|c| Vec2::new(uvs[6 * k + 2 * c], uvs[6 * k + 2 * c + 1])).sum::<Vec2>() / 3.0;
                let m = &fx.materials[t];
                let a = bilinear(&albedo, w, h, 3, uv);
                let r = bilinear(&mr, w, h, 3, uv);
                for c in 0..3 {
                    assert!((a[c] / 255.0 - srgb::encode(m.base_color[c])).abs() <= 1.0 / 255.0);
                }
                assert!((r[1] / 255.0 - m.roughness).abs() <= 0.5 / 255.0 + 1e-6);
                assert!((r[2] / 255.0 - m.metallic).abs() <= 0.5 / 255.0 + 1e-6);
                // Emission: factor ≤ 1 and factor × strength = the triangle's radiance.
                let e = fx.emission[t];
                if e.max_element() > 0.0 {
                    let f: Vec<f32> =
                        mat["emissiveFactor"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect();
                    let s = mat["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"].as_f64().unwrap()
                        as f32;
                    for c in 0..3 {
                        assert!((0.0..=1.0).contains(&f[c]));
                        assert!((f[c] * s - e[c]).abs() <= 1e-6 * e[c].max(1.0));
                    }
                } else {
                    assert!(mat.get("emissiveFactor").is_none());
                }
            }
            if mat.get("emissiveFactor").is_some() {
                emissive += 1;
            }
            total_corners += count;
        }
    }
    assert_eq!(total_corners, 3 * fx.triangles.len());
    assert_eq!(emissive, 1);
    assert_eq!(report.glb.emissive_materials, 1);
    // z_up: one root node with the −90° X rotation, whose children are the segment nodes.
    let scene_nodes = doc["scenes"][0]["nodes"].as_array().unwrap();
    assert_eq!(scene_nodes.len(), 1);
    let root = &doc["nodes"][scene_nodes[0].as_u64().unwrap() as usize];
    assert_eq!(root["children"].as_array().unwrap().len(), 4);
    let q: Vec<f64> = root["rotation"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((q.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-6, "unit quaternion");
}

#[test]
fn invalid_input_fails_before_writing() {
    let fx = Fixture::grid(2, 2, 4);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("export");
    let short = &fx.segment_id[1..];
    let bad = ExportInput { segment_id: short, ..fx.input() };
    assert!(matches!(export::write_all(&out, &bad, &ExportOptions::default()), Err(export::ExportError::Input { .. })));
    let mut neg = fx.emission.clone();
    neg[3] = Vec3::new(0.0, -1.0, 0.0);
    let bad = ExportInput { emission: &neg, ..fx.input() };
    assert!(matches!(
        export::write_all(&out, &bad, &ExportOptions::default()),
        Err(export::ExportError::Triangle { triangle: 3, .. })
    ));
    let mut nan = fx.materials.clone();
    nan[5].roughness = f32::NAN;
    let bad = ExportInput { materials: &nan, ..fx.input() };
    assert!(matches!(
        export::write_all(&out, &bad, &ExportOptions::default()),
        Err(export::ExportError::Triangle { triangle: 5, .. })
    ));
    let tris = vec![[0, 1, 99]];
    let bad = ExportInput {
        triangles: &tris,
        materials: &fx.materials[..1],
        emission: &fx.emission[..1],
        segment_id: &fx.segment_id[..1],
        ..fx.input()
    };
    assert!(export::write_all(&out, &bad, &ExportOptions::default()).is_err());
    assert!(!out.exists(), "nothing written for invalid input");
}

#[test]
fn per_object_values_expand_to_triangles() {
    let mats = [Material::default(), Material { roughness: 0.1, ..Material::default() }];
    let emission = [Vec3::ZERO, Vec3::new(2.0, 1.0, 0.0)];
    let per = export::expand_per_object(&[1, 0, 1], &[40, -3], &mats, &emission).unwrap();
    assert_eq!(per.segment_id, [-3, 40, -3]);
    assert_eq!(per.materials, [mats[1], mats[0], mats[1]]);
    assert_eq!(per.emission, [emission[1], emission[0], emission[1]]);
    assert!(matches!(
        export::expand_per_object(&[2], &[40, -3], &mats, &emission),
        Err(export::ExportError::Triangle { triangle: 0, .. })
    ));
    assert!(export::expand_per_object(&[0], &[1 << 40, 1], &mats, &emission).is_err());
    assert!(export::expand_per_object(&[0], &[1], &mats, &emission).is_err());
}
