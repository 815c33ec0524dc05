//! Feed anything: every reader of the crate gets `IPT_FUZZ_CASES` (default 10⁴) seeded mutations of valid
//! inputs, and must never panic, must name the file in a one-line error, must not allocate beyond a small
//! multiple of its input at once and must not be pathologically slow (see `fuzz_support`). Saved failing cases
//! (`tests/fuzz/regressions/`) are replayed on every run.
//!
//! `unsafe` is allowed in this test binary for two purposes: the counting `#[global_allocator]`
//! (`fuzz_support::alloc`), which must implement the unsafe `GlobalAlloc` trait, and reading the thread's CPU
//! time (`libc::clock_gettime`).
#![allow(unsafe_code)]

mod formats_common;
mod fuzz_support;

use fuzz_support::{alloc::CountingAlloc, fuzz, replay_regressions};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn regressions_replay() {
    let (replayed, failures) = replay_regressions();
    assert!(failures.is_empty(), "{} of {replayed} saved cases fail:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn fuzz_ply() {
    fuzz("ply");
}

#[test]
fn fuzz_matterport_conf() {
    fuzz("matterport_conf");
}

#[test]
fn fuzz_matterport_intrinsics() {
    fuzz("matterport_intrinsics");
}

#[test]
fn fuzz_matterport_pose() {
    fuzz("matterport_pose");
}

#[test]
fn fuzz_colmap_cameras() {
    fuzz("colmap_cameras");
}

#[test]
fn fuzz_colmap_images() {
    fuzz("colmap_images");
}

#[test]
fn fuzz_transforms() {
    fuzz("transforms");
}

#[test]
fn fuzz_obj() {
    fuzz("obj");
}

#[test]
fn fuzz_mtl() {
    fuzz("mtl");
}

#[test]
fn fuzz_image_header() {
    fuzz("image_header");
}

#[test]
fn fuzz_photo() {
    fuzz("photo");
}

#[test]
fn fuzz_matterport_fsegs() {
    fuzz("matterport_fsegs");
}

#[test]
fn fuzz_matterport_semseg() {
    fuzz("matterport_semseg");
}

#[test]
fn fuzz_photo_cache() {
    fuzz("photo_cache");
}

/// The harness itself: a reader that panics, allocates out of proportion or returns a bad message is caught.
#[test]
fn harness_detects_each_failure_kind() {
    use fuzz_support::readers::Reader;
    use fuzz_support::{run_case, violation};
    let path = std::path::PathBuf::from("/fuzz/x.txt");
    let check = |run: fn(&std::path::Path, &[u8]) -> Result<(), String>| {
        let r = Reader { name: "selftest", path: || "/fuzz/x.txt".into(), seeds: Vec::new, run };
        violation(&path, 10, &run_case(&r, &path, b"0123456789"))
    };
    assert!(check(|_, _| Ok(())).is_none());
    assert!(check(|_, _| Err("/fuzz/x.txt: bad".into())).is_none());
    assert!(check(|_, b| Err(format!("index {} out of range", b.len() * 99))).unwrap().contains("does not name"));
    assert!(check(|_, _| Err("x.txt: one\ntwo".into())).unwrap().contains("not one line"));
    assert!(check(|_, b| panic!("boom {}", b.len())).unwrap().contains("boom 10"));
    assert!(
        check(|_, b| {
            std::hint::black_box(vec![0u8; (b.len() << 20) + (4 << 20)]);
            Ok(())
        })
        .unwrap()
        .contains("allocated")
    );
}

/// Writes the inputs behind the bugs fixed when the fuzzer was introduced (found by it or by review) into
/// `tests/fuzz/regressions/<reader>/found-*.bin`, where `regressions_replay` keeps checking them. Run once with
/// `cargo test -p ingest --test fuzz_readers -- --ignored write_found_regressions`.
#[test]
#[ignore = "writes files into the source tree"]
fn write_found_regressions() {
    use fuzz_support::readers::{corpus, reader};
    let save = |r: &str, name: &str, bytes: &[u8]| {
        let dir = fuzz_support::regression_dir(r);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(format!("found-{name}.bin")), bytes).unwrap();
    };
    let jpeg = corpus(&reader("photo"))[3].clone();
    let hdr = corpus(&reader("photo"))[7].clone();
    for r in ["photo", "image_header"] {
        // zune-jpeg's message ends with a newline.
        save(r, "jpeg-truncated-multiline-error", &jpeg[..300]);
        // The image crate quotes the unknown leading bytes, control characters included.
        let mut garbled = hdr.clone();
        garbled[0] = b'3';
        garbled[1] = b'2';
        garbled.splice(2..2, b"\r\r\0\t".iter().copied());
        save(r, "unknown-format-control-bytes", &garbled);
    }
    save("mtl", "kd-one-number-panics-tobj", b"newmtl white\nKd 0.8\nnewmtl red\nKs\n");
    save("obj", "normal-index-overflows-tobj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//-2147483648\n");
    save("obj", "zero-index", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n");
    save(
        "ply",
        "empty-element-huge-count",
        b"ply\nformat ascii 1.0\nelement junk 18446744073709551615\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    );
    save(
        "ply",
        "second-vertex-element",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n5 5 5\n",
    );
    save(
        "ply",
        "uchar-out-of-range",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nproperty uchar segment_id\nend_header\n\
0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1e38\n",
    );
    save("matterport_intrinsics", "width-beyond-u32", b"1e20 480 500 500 320 240 0 0 0 0 0\n");
    save(
        "transforms",
        "zero-field-of-view",
        br#"{"camera_angle_x": 0, "frames": [{"file_path": "a.png",
"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}"#,
    );
    save(
        "transforms",
        "line-break-in-file-path",
        br#"{"fl_x": 10, "frames": [{"file_path": "a\nb.png",
"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}"#,
    );
    save("colmap_cameras", "zero-width", b"1 PINHOLE 0 7 10 10 6.5 3.5\n");
}

/// Reproduces one case from its seed: `IPT_FUZZ_CASE=<reader>:<seed>:<case> cargo test -p ingest --test
/// fuzz_readers -- --ignored --nocapture reproduce_case` runs it five times, prints its outcome, times and
/// largest allocation, and saves it under `tests/fuzz/regressions/<reader>/<seed>-<case>.bin`.
#[test]
#[ignore = "reproduces the case named by IPT_FUZZ_CASE"]
fn reproduce_case() {
    use fuzz_support::readers::{corpus, reader};
    let spec = std::env::var("IPT_FUZZ_CASE").expect("set IPT_FUZZ_CASE=<reader>:<seed>:<case>");
    let parts: Vec<&str> = spec.split(':').collect();
    let [name, seed, case] = parts[..] else { panic!("IPT_FUZZ_CASE={spec:?} is not <reader>:<seed>:<case>") };
    let r = reader(name);
    let (seed, case) = (seed.parse().unwrap(), case.parse().unwrap());
    let bytes = fuzz_support::case_bytes(&r, &corpus(&r), seed, case);
    let path = (r.path)();
    for _ in 0..5 {
        let run = fuzz_support::run_case(&r, &path, &bytes);
        println!("{:?} in {:?}, largest allocation {} bytes", run.outcome, run.time, run.largest_alloc);
    }
    println!("saved {}", fuzz_support::save_case(r.name, seed, case, &bytes).display());
}
