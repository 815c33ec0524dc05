//! PLY reader/writer: round trips, ASCII and binary variants, and one test per bad-input case.

mod formats_common;

use formats_common::{assert_mentions, binary_ply};
use glam::Vec3;
use ingest::ply::{FaceProperty, FaceValues, PlyMesh, read_ply, read_ply_bytes, write_ply};
use std::path::Path;

fn sample_mesh() -> PlyMesh {
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.5),
        Vec3::new(-2.5, 3.25, 1e-7),
    ];
    let normals = positions.iter().map(|p| (*p + Vec3::Z).normalize()).collect();
    PlyMesh {
        positions,
        normals: Some(normals),
        triangles: vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]],
        face_props: vec![
            FaceProperty { name: "albedo_r".into(), values: FaceValues::F32(vec![0.25, 0.5, 0.875]) },
            FaceProperty { name: "segment_id".into(), values: FaceValues::I32(vec![7, -1, 123_456]) },
            FaceProperty { name: "red".into(), values: FaceValues::U8(vec![0, 128, 255]) },
        ],
    }
}

#[test]
fn binary_round_trip_preserves_everything() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.ply");
    let mesh = sample_mesh();
    write_ply(&path, &mesh).unwrap();
    let back = read_ply(&path).unwrap();
    assert_eq!(back.mesh, mesh);
    assert_eq!(back.face_count, 3);
    assert_eq!(back.polygons_triangulated, 0);
    assert_eq!(back.source_face, vec![0, 1, 2]);
    // Only the final file is left in the directory (the temporary file was renamed).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn writer_output_size_matches_binary_layout() {
    // 5 vertices x 6 floats + 3 faces x (1 + 3*4 + 4 + 4 + 1) bytes after the header.
    let bytes = ingest::ply::encode_ply(Path::new("x.ply"), &sample_mesh()).unwrap();
    let header_end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    assert_eq!(bytes.len() - header_end, 5 * 24 + 3 * 22);
}

#[test]
fn ascii_with_extra_props_polygons_and_other_elements() {
    let text = "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement vertex 5\r\nproperty double x\r\n\
        property double y\r\nproperty double z\r\nproperty uchar red\r\nproperty uchar green\r\nproperty uchar blue\r\n\
        property float tx\r\nproperty list uchar float extra\r\nelement face 2\r\nproperty list uchar uint vertex_indices\r\n\
        property int material_id\r\nproperty int segment_id\r\nproperty int category_id\r\nelement edge 1\r\n\
        property int vertex1\r\nproperty int vertex2\r\nend_header\r\n\
        0 0 0 255 0 0 0.5 0\r\n1 0 0 255 0 0 0.5 2 1.0 2.0\r\n1 1 0 255 0 0 0.5 0\r\n0 1 0 1 2 3 4 0\r\n2 2 2 1 1 1 1 0\r\n\
        4 0 1 2 3 11 21 31\r\n3 2 3 4 12 22 32\r\n0 1\r\n";
    let r = read_ply_bytes(Path::new("hand.ply"), text.as_bytes()).unwrap();
    assert_eq!(r.mesh.positions.len(), 5);
    assert!(r.mesh.normals.is_none(), "no nx/ny/nz in the file");
    // The quad becomes a fan of two triangles, each carrying the quad's ids.
    assert_eq!(r.mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [2, 3, 4]]);
    assert_eq!(r.source_face, vec![0, 0, 1]);
    assert_eq!(r.polygons_triangulated, 1);
    assert_eq!(r.mesh.face_ids("material_id").unwrap(), vec![11, 11, 12]);
    assert_eq!(r.mesh.face_ids("segment_id").unwrap(), vec![21, 21, 22]);
    assert_eq!(r.mesh.face_ids("category_id").unwrap(), vec![31, 31, 32]);
    assert_eq!(r.mesh.positions[4], Vec3::splat(2.0));
}

#[test]
fn big_endian_and_alternative_type_names() {
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float32 x\nproperty float32 y\n\
        property float32 z\nproperty int16 junk\nelement face 1\nproperty list uint8 int32 vertex_indices\n\
        property uint8 segment_id\nend_header\n"
        .to_vec();
    for (v, junk) in [([0.0f32, 0.0, 0.0], 1i16), ([1.0, 0.0, 0.0], 2), ([0.0, 2.0, 0.0], 3)] {
        for c in v {
            b.extend_from_slice(&c.to_be_bytes());
        }
        b.extend_from_slice(&junk.to_be_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    b.push(200);
    let r = read_ply_bytes(Path::new("be.ply"), &b).unwrap();
    assert_eq!(r.mesh.positions[2], Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(r.mesh.face_prop("segment_id"), Some(&FaceValues::U8(vec![200])));
}

#[test]
fn truncated_binary_names_file_and_element() {
    let bytes = binary_ply(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
        &[(vec![0, 1, 2], 1), (vec![1, 3, 2, 0, 1, 2, 3, 0], 2)],
    );
    // The second face's list is longer than the minimum row size, so cutting into it passes the header-size check
    // and is caught while reading.
    let cut = &bytes[..bytes.len() - 10];
    let err = read_ply_bytes(Path::new("trunc.ply"), cut).unwrap_err();
    assert_mentions(&err, &["trunc.ply", "face 1", "truncated"]);
    // Cut inside the vertices: caught by the size check, which names the first vertex that cannot be there.
    let header_len = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let cut = &bytes[..header_len + 12 * 2 + 5];
    let err = read_ply_bytes(Path::new("trunc_v.ply"), cut).unwrap_err();
    assert_mentions(&err, &["trunc_v.ply", "vertex 2", "truncated"]);
}

#[test]
fn face_index_out_of_range_names_face() {
    let bytes = binary_ply(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[(vec![0, 1, 2], 0), (vec![0, 1, 3], 0)]);
    let err = read_ply_bytes(Path::new("oob.ply"), &bytes).unwrap_err();
    assert_mentions(&err, &["oob.ply", "face 1", "vertex index 3 is out of range", "3 vertices"]);
    let bytes = binary_ply(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[(vec![0, -1, 2], 0)]);
    let err = read_ply_bytes(Path::new("neg.ply"), &bytes).unwrap_err();
    assert_mentions(&err, &["neg.ply", "face 0", "-1"]);
}

#[test]
fn face_with_fewer_than_three_indices_is_an_error() {
    let bytes = binary_ply(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[(vec![0, 1, 2], 0), (vec![0, 1], 0)]);
    let err = read_ply_bytes(Path::new("line.ply"), &bytes).unwrap_err();
    assert_mentions(&err, &["line.ply", "face 1", "at least 3"]);
}

#[test]
fn nan_and_inf_vertices_name_the_vertex() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let bytes = binary_ply(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, bad, 0.0]], &[(vec![0, 1, 2], 0)]);
        let err = read_ply_bytes(Path::new("nan.ply"), &bytes).unwrap_err();
        assert_mentions(&err, &["nan.ply", "vertex 2", "not finite"]);
    }
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n";
    let err = read_ply_bytes(Path::new("nan_ascii.ply"), text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["nan_ascii.ply", "vertex 1", "not finite"]);
}

#[test]
fn header_claiming_more_elements_than_file_holds_fails_before_allocating() {
    // 10^15 vertices of 12 bytes would be a 12 PB allocation; the size check must reject it first.
    let mut bytes = binary_ply(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[(vec![0, 1, 2], 0)]);
    let header = String::from_utf8_lossy(&bytes[..120]).into_owned();
    let patched = header.replacen("element vertex 3", "element vertex 1000000000000000", 1);
    bytes.splice(..120, patched.into_bytes());
    let err = read_ply_bytes(Path::new("huge.ply"), &bytes).unwrap_err();
    assert_mentions(&err, &["huge.ply", "1000000000000000", "\"vertex\"", "cannot hold"]);
    // Overflowing usize is reported the same way.
    let text = "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty double x\n\
        property double y\nproperty double z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    let err = read_ply_bytes(Path::new("overflow.ply"), text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["overflow.ply", "cannot hold"]);
    // ASCII too: 5 faces cannot fit in 4 bytes.
    let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
        element face 5\nproperty list uchar int vertex_indices\nend_header\n0 0\n";
    let err = read_ply_bytes(Path::new("ascii_huge.ply"), text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["ascii_huge.ply", "cannot hold"]);
}

#[test]
fn unknown_property_type_names_line() {
    let text = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty half y\n";
    let err = read_ply_bytes(Path::new("half.ply"), text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["half.ply:5", "unknown PLY property type \"half\""]);
    let text = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar quad vertex_indices\nend_header\n";
    let err = read_ply_bytes(Path::new("quad.ply"), text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["quad.ply:4", "\"quad\""]);
}

#[test]
fn bad_headers_are_errors() {
    let cases: [(&str, &[&str]); 6] = [
        ("plx\nformat ascii 1.0\nend_header\n", &["bad.ply:1", "not \"ply\""]),
        ("ply\nformat ascii 1.0\nelement vertex 1\n", &["bad.ply", "end_header"]),
        ("ply\nformat utf16 1.0\nend_header\n", &["bad.ply:2", "unknown format"]),
        ("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", &["bad.ply:3", "not a count"]),
        ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", &["bad.ply:3", "before any `element`"]),
        ("ply\nelement vertex 0\nend_header\n", &["bad.ply", "no `format`"]),
    ];
    for (text, needles) in cases {
        let err = read_ply_bytes(Path::new("bad.ply"), text.as_bytes()).unwrap_err();
        assert_mentions(&err, needles);
    }
    let no_faces = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
        end_header\n0 0 0\n";
    assert_mentions(&read_ply_bytes(Path::new("pts.ply"), no_faces.as_bytes()).unwrap_err(), &["pts.ply", "no `face`"]);
    let missing = read_ply(Path::new("/nonexistent/dir/none.ply")).unwrap_err();
    assert_mentions(&missing, &["/nonexistent/dir/none.ply"]);
}

#[test]
fn writer_rejects_inconsistent_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.ply");
    let mut m = sample_mesh();
    m.triangles[1] = [0, 9, 1];
    assert_mentions(&write_ply(&path, &m).unwrap_err(), &["w.ply", "face 1", "out of range"]);
    let mut m = sample_mesh();
    m.face_props[0].values = FaceValues::F32(vec![1.0]);
    assert_mentions(&write_ply(&path, &m).unwrap_err(), &["albedo_r", "1 values for 3 faces"]);
    let mut m = sample_mesh();
    m.face_props[1].name = "bad name".into();
    assert_mentions(&write_ply(&path, &m).unwrap_err(), &["bad name"]);
    assert!(!path.exists(), "a failed write leaves nothing behind");
}

#[test]
fn write_atomic_replaces_whole_files_and_reports_paths() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.bin");
    ingest::write_atomic(&path, b"first version, longer").unwrap();
    ingest::write_atomic(&path, b"second").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"second");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left behind");
    let missing_dir = dir.path().join("no/such/dir/x.bin");
    let err = ingest::write_atomic(&missing_dir, b"x").unwrap_err();
    assert_mentions(&err, &["no/such/dir"]);
}
