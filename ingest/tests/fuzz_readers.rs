//! Feed anything: every reader of the crate gets `IPT_FUZZ_CASES` (default 10⁴) seeded mutations of valid
//! inputs, and must never panic, must name the file in a one-line error, must not allocate beyond a small
//! multiple of its input at once and must not be pathologically slow (see `fuzz_support`). Saved failing cases
//! (`tests/fuzz/regressions/`) are replayed on every run.
//!
//! `unsafe` is allowed in this test binary for one purpose: the counting `#[global_allocator]`
//! (`fuzz_support::alloc`), which must implement the unsafe `GlobalAlloc` trait.
#![allow(unsafe_code)]

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
