//! The fuzzed readers: for each, its valid seed corpus (generated here, plus any files committed under
//! `tests/fuzz/seeds/<reader>/`), the path its errors must name, and how one case is fed to it.
//!
//! Readers that take a path are fed through their byte-slice entry points (`read_ply_bytes`, `parse_conf`,
//! `parse_cameras`, ...). `transforms.json` still resolves and opens the images it lists, so its cases are
//! parsed as if they were the file `transforms.json` of a temporary directory holding those images.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::{DMat3, DMat4, DQuat, DVec3, Vec3};
use ingest::mesh::{LabeledMesh, Mesh};
use ingest::ply::{FaceProperty, FaceValues, PlyMesh};
use ingest::{GroupBy, scan};

/// One fuzzed reader.
#[derive(Debug, Clone, Copy)]
pub struct Reader {
    /// Directory name under `tests/fuzz/{seeds,regressions}/`.
    pub name: &'static str,
    /// The file a case stands for; every error message must contain its file name.
    pub path: fn() -> PathBuf,
    /// The generated valid inputs.
    pub seeds: fn() -> Vec<Vec<u8>>,
    /// Feeds one case; `Err` carries the error's message.
    pub run: fn(&Path, &[u8]) -> Result<(), String>,
}

/// Every fuzzed reader.
pub const READERS: &[Reader] = &[
    Reader { name: "ply", path: || "/fuzz/case.ply".into(), seeds: ply_seeds, run: run_ply },
    Reader { name: "matterport_conf", path: || "/fuzz/house.conf".into(), seeds: conf_seeds, run: run_conf },
    Reader {
        name: "matterport_intrinsics",
        path: || "/fuzz/u_intrinsics_0.txt".into(),
        seeds: raw_intrinsics_seeds,
        run: run_raw_intrinsics,
    },
    Reader {
        name: "matterport_pose",
        path: || "/fuzz/u_pose_0_0.txt".into(),
        seeds: raw_pose_seeds,
        run: run_raw_pose,
    },
    Reader { name: "colmap_cameras", path: || "/fuzz/cameras.txt".into(), seeds: cameras_seeds, run: run_cameras },
    Reader { name: "colmap_images", path: || "/fuzz/images.txt".into(), seeds: images_seeds, run: run_images },
    Reader { name: "transforms", path: transforms_path, seeds: transforms_seeds, run: run_transforms },
    Reader { name: "obj", path: || "/fuzz/room.obj".into(), seeds: obj_seeds, run: run_obj },
    Reader { name: "mtl", path: || "/fuzz/room.obj".into(), seeds: mtl_seeds, run: run_mtl },
    Reader { name: "image_header", path: || "/fuzz/photo.img".into(), seeds: image_seeds, run: run_image_header },
    Reader { name: "photo", path: || "/fuzz/photo.img".into(), seeds: image_seeds, run: run_photo },
    Reader { name: "matterport_fsegs", path: || "/fuzz/h.fsegs.json".into(), seeds: fsegs_seeds, run: run_fsegs },
    Reader { name: "matterport_semseg", path: || "/fuzz/h.semseg.json".into(), seeds: semseg_seeds, run: run_semseg },
    Reader { name: "photo_cache", path: || cache_dir().join("view.json"), seeds: manifest_seeds, run: run_manifest },
];

/// The reader called `name`.
pub fn reader(name: &str) -> Reader {
    *READERS.iter().find(|r| r.name == name).unwrap_or_else(|| panic!("no fuzzed reader {name:?}"))
}

/// The seed corpus of `r`: generated seeds, then committed ones in file-name order.
pub fn corpus(r: &Reader) -> Vec<Vec<u8>> {
    let mut out = (r.seeds)();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/seeds").join(r.name);
    if let Ok(entries) = std::fs::read_dir(&dir) {
        let mut files: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        files.sort();
        out.extend(files.iter().filter_map(|f| std::fs::read(f).ok()));
    }
    out
}

fn msg(e: impl std::fmt::Display) -> String {
    e.to_string()
}

// ---------------------------------------------------------------------------------------------------------
// PLY

fn sample_ply_mesh(normals: bool) -> PlyMesh {
    let positions: Vec<Vec3> =
        (0..8).map(|i| Vec3::new((i % 2) as f32, ((i / 2) % 2) as f32, (i / 4) as f32 * 0.5 - 0.25)).collect();
    let triangles = vec![[0, 1, 3], [0, 3, 2], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4]];
    let n = triangles.len();
    PlyMesh {
        normals: normals.then(|| positions.iter().map(|p| p.normalize_or(Vec3::Z)).collect()),
        positions,
        triangles,
        face_props: vec![
            FaceProperty { name: "segment_id".into(), values: FaceValues::I32((0..n as i32).map(|i| i / 2).collect()) },
            FaceProperty { name: "category_id".into(), values: FaceValues::U8(vec![3; n]) },
            FaceProperty { name: "material_id".into(), values: FaceValues::I32(vec![7; n]) },
            FaceProperty { name: "weight".into(), values: FaceValues::F32(vec![0.5; n]) },
        ],
    }
}

fn ply_seeds() -> Vec<Vec<u8>> {
    let p = Path::new("seed.ply");
    let mut out = vec![
        ingest::ply::encode_ply(p, &sample_ply_mesh(true)).unwrap(),
        ingest::ply::encode_ply(p, &sample_ply_mesh(false)).unwrap(),
    ];
    out.push(
        b"ply\nformat ascii 1.0\ncomment made by hand\nobj_info fuzz seed\nelement vertex 5\nproperty float x\n\
property float y\nproperty float z\nproperty uchar red\nproperty list uchar float extra\nelement camera 1\n\
property float view_px\nproperty list uint uchar tags\nelement face 3\nproperty list uchar int vertex_indices\n\
property int segment_id\nproperty uchar category_id\nproperty list uchar int unused\nend_header\n\
0 0 0 255 0\n1 0 0 128 2 0.5 0.25\n1 1 0 0 1 1.0\n0 1 0 3 0\n0.5 0.5 1 9 0\n\
2.5 3 1 2 3\n\
4 0 1 2 3 5 1 0\n3 0 1 4 6 2 1 2\n3 1 2 4 6 3 0\n"
            .to_vec(),
    );
    // Big-endian, `vertex_index` spelling, uint items, a double coordinate and an element without properties.
    let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\nproperty float y\n\
property float z\nelement empty 2\nelement face 2\nproperty list uchar uint vertex_index\nproperty short segment_id\n\
end_header\n"
        .to_vec();
    for (x, y, z) in [(0.0f64, 0.0f32, 0.0f32), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.5)] {
        be.extend_from_slice(&x.to_be_bytes());
        be.extend_from_slice(&y.to_be_bytes());
        be.extend_from_slice(&z.to_be_bytes());
    }
    for (face, seg) in [([0u32, 1, 2], 4i16), ([0, 2, 3], -1)] {
        be.push(3);
        for i in face {
            be.extend_from_slice(&i.to_be_bytes());
        }
        be.extend_from_slice(&seg.to_be_bytes());
    }
    out.push(be);
    out
}

/// Reads the PLY and assembles it into a scan (zero-area removal, grouping), as `load_scan` does, so that an
/// inconsistent mesh that the reader let through would panic here.
fn run_ply(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let read = ingest::ply::read_ply_bytes(path, bytes).map_err(msg)?;
    let ids = read.mesh.face_ids("segment_id");
    let mut mesh = Mesh::without_ids(read.mesh.positions, read.mesh.normals, read.mesh.triangles);
    if let Some(ids) = ids {
        mesh.face_segment = ids;
    }
    let scan = scan::assemble(LabeledMesh { mesh, ..LabeledMesh::default() }, path, Vec::new(), GroupBy::Segment);
    std::hint::black_box(scan);
    Ok(())
}

// ---------------------------------------------------------------------------------------------------------
// Camera files

fn rigid(seed: u64) -> DMat4 {
    let a = seed as f64 * 0.7 + 0.3;
    let q = DQuat::from_euler(glam::EulerRot::XYZ, a, 2.0 * a, -0.5 * a);
    DMat4::from_rotation_translation(q, DVec3::new(a, -a, 1.5))
}

fn row_major(m: &DMat4) -> String {
    m.transpose().to_cols_array().iter().map(|v| format!("{v:.9}")).collect::<Vec<_>>().join(" ")
}

fn conf_seeds() -> Vec<Vec<u8>> {
    let mut a = String::from(
        "dataset matterport\nn_images 3\ndepth_directory undistorted_depth_images\n\
         color_directory undistorted_color_images\n\nintrinsics_matrix 1075.1 0 629.7 0 1074.1 522.0 0 0 1\n",
    );
    for i in 0..2 {
        a += &format!("scan u_d0_{i}.png u_i0_{i}.jpg {}\n", row_major(&rigid(i)));
    }
    a += "intrinsics_matrix 1070 0 640.5 0 1071 510.25 0 0 1\n";
    a += &format!("scan u_d1_0.png u_i1_0.jpg {}\n", row_major(&rigid(5)));
    let b = format!(
        "n_images 1\nintrinsics_matrix 500 0 320 0 500 240 0 0 1\nscan d.png c.jpg {}\nunknown_key 1 2\n",
        row_major(&DMat4::IDENTITY)
    );
    vec![a.into_bytes(), b.into_bytes()]
}

fn run_conf(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::matterport::parse_conf(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn raw_intrinsics_seeds() -> Vec<Vec<u8>> {
    vec![
        b"1280 1024 1075.1 1074.1 629.7 522.0 -0.1 0.02 0.001 -0.002 0.003\n".to_vec(),
        b"640 480\n500.5 501 320 240\n0 0 0 0 0".to_vec(),
    ]
}

fn run_raw_intrinsics(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::matterport::parse_raw_intrinsics(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn raw_pose_seeds() -> Vec<Vec<u8>> {
    let m = rigid(3).transpose().to_cols_array();
    let rows: Vec<String> =
        m.chunks(4).map(|r| r.iter().map(|v| format!("{v:.6}")).collect::<Vec<_>>().join(" ")).collect();
    vec![rows.join("\n").into_bytes(), row_major(&DMat4::IDENTITY).into_bytes()]
}

fn run_raw_pose(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::matterport::parse_raw_pose(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn cameras_seeds() -> Vec<Vec<u8>> {
    vec![
        b"# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n\
# Number of cameras: 6\n1 SIMPLE_PINHOLE 100 80 90 50 40\n2 PINHOLE 100 80 90 91 50.5 40.5\n\
3 SIMPLE_RADIAL 100 80 90 50 40 -0.1\n4 RADIAL 100 80 90 50 40 -0.1 0.02\n\
5 OPENCV 13 7 90 91 50 40 -0.1 0.02 0.001 0.002\n\
6 FULL_OPENCV 100 80 90 91 50 40 -0.1 0.02 0.001 0.002 0.003 0.1 0.01 0.001\n"
            .to_vec(),
    ]
}

fn run_cameras(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::colmap::parse_cameras(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn images_seeds() -> Vec<Vec<u8>> {
    let mut s = String::from(
        "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n# Number of images: 3\n",
    );
    for i in 0..3u64 {
        let q = DQuat::from_mat3(&DMat3::from_mat4(rigid(i)));
        s += &format!(
            "{} {:.17} {:.17} {:.17} {:.17} 0.5 -1.25 3 {} view {i}.jpg\n",
            i + 1,
            q.w,
            q.x,
            q.y,
            q.z,
            1 + i % 2
        );
        s += if i % 2 == 0 { "\n" } else { "12.5 3.5 -1 20.0 7.25 4\n" };
    }
    vec![s.into_bytes()]
}

fn run_images(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::colmap::parse_images(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

/// The directory of the fuzzed `transforms.json`: the images its seeds list (13×7, the photo seed size).
fn transforms_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let seeds = image_seeds();
        std::fs::create_dir_all(dir.path().join("train")).unwrap();
        std::fs::write(dir.path().join("a.png"), &seeds[0]).unwrap();
        std::fs::write(dir.path().join("b.jpg"), &seeds[3]).unwrap();
        std::fs::write(dir.path().join("train/r_0.png"), &seeds[0]).unwrap();
        std::fs::write(dir.path().join("train/r_0.exr"), &seeds[4]).unwrap();
        dir
    })
    .path()
}

fn transforms_path() -> PathBuf {
    transforms_dir().join("transforms.json")
}

fn transforms_seeds() -> Vec<Vec<u8>> {
    let m = |s: u64| {
        let r = rigid(s).to_cols_array_2d();
        // Rows of the row-major matrix are the columns of the transpose.
        let rows: Vec<String> =
            (0..4).map(|i| format!("[{}, {}, {}, {}]", r[0][i], r[1][i], r[2][i], r[3][i])).collect();
        format!("[{}]", rows.join(", "))
    };
    let a = format!(
        r#"{{"camera_model": "OPENCV", "fl_x": 20.5, "fl_y": 20, "cx": 6.5, "cy": 3.5, "w": 13, "h": 7,
"k1": -0.01, "k2": 0.001, "p1": 0.0, "p2": 0.0,
"frames": [{{"file_path": "a.png", "transform_matrix": {}}},
           {{"file_path": "./b.jpg", "transform_matrix": {}, "fl_x": 19}}]}}"#,
        m(1),
        m(2)
    );
    let b = format!(
        r#"{{"camera_angle_x": 0.69, "frames": [{{"file_path": "./train/r_0", "rotation": 0.1,
"transform_matrix": {}}}]}}"#,
        m(4)
    );
    vec![a.into_bytes(), b.into_bytes()]
}

fn run_transforms(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::transforms::load_views_bytes(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

// ---------------------------------------------------------------------------------------------------------
// OBJ / MTL

const OBJ: &str = "# room\nmtllib room.mtl\no floor\nv -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\nvt 0 0\nvt 1 0\nvt 1 1\n\
vn 0 0 1\nusemtl white\ns off\nf 1/1/1 2/2/1 3/3/1 4/1/1\no box\nv 0 0 0\nv 0.5 0 0\nv 0.5 0.5 0\nv 0 0.5 1\n\
usemtl red\nf 5 6 7\nf -4 -2 -1\ng hidden part\nusemtl white\nf 5//1 6//1 8//1\nl 1 2\np 3\n";

const MTL: &str = "# materials\nnewmtl white\nKa 0 0 0\nKd 0.8 0.8 0.8\nKs 0.1 0.1 0.1\nNs 10\nd 1\nillum 2\n\
map_Kd white.png\nnewmtl red\nKd 0.8 0.1 0.1\nNi 1.5\nTr 0\n";

fn obj_seeds() -> Vec<Vec<u8>> {
    vec![OBJ.as_bytes().to_vec(), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 2 3 4 1\n".to_vec()]
}

fn mtl_seeds() -> Vec<Vec<u8>> {
    vec![MTL.as_bytes().to_vec()]
}

fn assemble_obj(path: &Path, labeled: LabeledMesh) {
    std::hint::black_box(scan::assemble(labeled, path, Vec::new(), GroupBy::OBJ_MATERIAL));
}

fn run_obj(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let labeled = ingest::obj::load_obj_bytes(path, bytes, Some(MTL.as_bytes())).map_err(msg)?;
    assemble_obj(path, labeled);
    Ok(())
}

fn run_mtl(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let labeled = ingest::obj::load_obj_bytes(path, OBJ.as_bytes(), Some(bytes)).map_err(msg)?;
    assemble_obj(path, labeled);
    Ok(())
}

// ---------------------------------------------------------------------------------------------------------
// Images

/// Every photo seed is this size, which the photo reader is told to expect (as `prepare_view` tells it the
/// camera's size).
pub const PHOTO_SIZE: (u32, u32) = (13, 7);

/// PNG 8-bit RGB, PNG 16-bit grey + alpha, PNG 8-bit RGBA, JPEG, EXR RGB, EXR RGB + mask, Radiance HDR.
fn image_seeds() -> Vec<Vec<u8>> {
    let (w, h) = PHOTO_SIZE;
    let encode = |img: image::DynamicImage, format: image::ImageFormat| {
        let mut out = Cursor::new(Vec::new());
        img.write_to(&mut out, format).unwrap();
        out.into_inner()
    };
    let rgb = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 19) as u8, (y * 37) as u8, 200]));
    let la16 = image::ImageBuffer::<image::LumaA<u16>, _>::from_fn(w, h, |x, y| {
        image::LumaA([(x * 5000) as u16, if (x + y) % 5 == 0 { 0 } else { 65535 }])
    });
    let rgba = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba([x as u8 * 20, 250, y as u8 * 30, 255]));
    let pixel = |x: usize, y: usize| [x as f32 * 0.1, y as f32 * 0.2, 0.5];
    let n = (w * h) as usize;
    let rgb_f: Vec<f32> = (0..n).flat_map(|i| pixel(i % w as usize, i / w as usize)).collect();
    let mask: Vec<u8> = (0..n).map(|i| u8::from(i % 7 != 0)).collect();
    let hdr = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([x as f32 * 0.3, y as f32, 2.0]));
    vec![
        encode(rgb.clone().into(), image::ImageFormat::Png),
        encode(la16.into(), image::ImageFormat::Png),
        encode(rgba.into(), image::ImageFormat::Png),
        encode(rgb.into(), image::ImageFormat::Jpeg),
        ingest::photo::exr::encode_rgb(w, h, ingest::photo::exr::Compression::Fast, pixel).unwrap(),
        ingest::photo::exr::encode_rgb_mask(w, h, &rgb_f, &mask).unwrap(),
        ingest::photo::exr::encode_rgb(w, h, ingest::photo::exr::Compression::Small, pixel).unwrap(),
        encode(hdr.into(), image::ImageFormat::Hdr),
        exr_with(vec![exr_channel("Y", n)], exr::prelude::Compression::ZIP1, exr::prelude::Blocks::ScanLines),
        exr_with(
            vec![exr_channel("B", n), exr_channel("G", n), exr_channel("R", n)],
            exr::prelude::Compression::PIZ,
            exr::prelude::Blocks::Tiles(exr::prelude::Vec2(4, 4)),
        ),
    ]
}

/// A half-float channel of `n` samples.
fn exr_channel(name: &str, n: usize) -> exr::prelude::AnyChannel<exr::prelude::FlatSamples> {
    let samples = (0..n).map(|i| exr::prelude::f16::from_f32(i as f32 / n as f32)).collect();
    exr::prelude::AnyChannel::new(name, exr::prelude::FlatSamples::F16(samples))
}

/// A single-layer EXR of the photo seed size with the given channels, compression and blocks.
fn exr_with(
    channels: Vec<exr::prelude::AnyChannel<exr::prelude::FlatSamples>>,
    compression: exr::prelude::Compression,
    blocks: exr::prelude::Blocks,
) -> Vec<u8> {
    use exr::prelude::{AnyChannels, Encoding, Image, Layer, LayerAttributes, LineOrder, WritableImage};
    let (w, h) = PHOTO_SIZE;
    let encoding = Encoding { compression, blocks, line_order: LineOrder::Increasing };
    let layer =
        Layer::new((w as usize, h as usize), LayerAttributes::default(), encoding, AnyChannels::sort(channels.into()));
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

// ---------------------------------------------------------------------------------------------------------
// Matterport side files and the photo cache manifest, fed as bytes (writing each case to disk would make the run
// wait on the disk, not on the reader).

/// The house mesh the side files describe (6 faces).
fn house_ply() -> &'static [u8] {
    static PLY: OnceLock<Vec<u8>> = OnceLock::new();
    PLY.get_or_init(|| {
        let mut mesh = sample_ply_mesh(false);
        mesh.face_props.retain(|p| p.name != "material_id");
        ingest::ply::encode_ply(Path::new("h.ply"), &mesh).unwrap()
    })
}

fn house_mesh() -> (PathBuf, ingest::ply::PlyRead) {
    let ply = PathBuf::from("/fuzz/h.ply");
    let read = ingest::ply::read_ply_bytes(&ply, house_ply()).unwrap();
    (ply, read)
}

fn fsegs_seeds() -> Vec<Vec<u8>> {
    vec![b"{\"sceneId\": \"h\", \"segIndices\": [100, 100, 101, 200, 200, -1]}".to_vec()]
}

fn semseg_seeds() -> Vec<Vec<u8>> {
    vec![
        br#"{"sceneId": "h", "segGroups": [
{"id": 0, "objectId": 0, "label": "chair", "segments": [100, 101], "obb": {"centroid": [0, 0, 0]}},
{"id": 1, "objectId": 1, "label": "table", "segments": [200]},
{"id": 2, "label": null, "segments": []}]}"#
            .to_vec(),
    ]
}

fn run_fsegs(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let (ply, read) = house_mesh();
    let labeled = ingest::matterport::mesh_from_ply_read(&ply, read, Some((path, bytes))).map_err(msg)?;
    std::hint::black_box(scan::assemble(labeled, &ply, Vec::new(), GroupBy::Material));
    Ok(())
}

fn run_semseg(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let (ply, read) = house_mesh();
    let mut labeled = ingest::matterport::mesh_from_ply_read(&ply, read, None).unwrap();
    ingest::matterport::apply_semseg_bytes(path, bytes, &mut labeled).map_err(msg)?;
    std::hint::black_box(scan::assemble(labeled, &ply, Vec::new(), GroupBy::Segment));
    Ok(())
}

/// A photo cache directory holding `view.exr` (13×7, R, G, B, mask) as written by `write_cached`.
fn cache_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = PHOTO_SIZE;
        let n = (w * h) as usize;
        let img =
            ingest::photo::LinearImage::new(w, h, vec![0.5; 3 * n], (0..n).map(|i| u8::from(i % 3 != 0)).collect())
                .unwrap();
        let camera = ingest::camera::Camera {
            width: w,
            height: h,
            intrinsics: ingest::camera::Intrinsics { fx: 10.0, fy: 10.0, cx: 6.0, cy: 3.0 },
            distortion: ingest::camera::Distortion::default(),
            cam_to_world: DMat4::IDENTITY,
        };
        ingest::photo::write_cached(dir.path(), "view", &camera, &img).unwrap();
        dir
    })
    .path()
}

fn manifest_seeds() -> Vec<Vec<u8>> {
    vec![std::fs::read(cache_dir().join("view.json")).unwrap()]
}

fn run_manifest(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let dir = path.parent().unwrap();
    ingest::photo::cache::read_cached_bytes(dir, "view", bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn run_image_header(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::image_header::image_dimensions_bytes(path, bytes).map(std::hint::black_box).map(drop).map_err(msg)
}

fn run_photo(path: &Path, bytes: &[u8]) -> Result<(), String> {
    ingest::photo::decode_image(path, bytes, Some(PHOTO_SIZE)).map(std::hint::black_box).map(drop).map_err(msg)
}
