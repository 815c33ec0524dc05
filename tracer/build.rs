//! Links the Embree 4.4 library that `scripts/setup` unpacks into `deps/embree/lib` (or `$IPT_EMBREE_LIB`).
//! The two shared objects are symlinked into OUT_DIR: cargo puts link-search paths inside the target
//! directory on LD_LIBRARY_PATH for `cargo run`/`cargo test`, and `.cargo/config.toml` adds an rpath for
//! binaries run directly.
use std::path::PathBuf;

const FILES: [&str; 3] = ["libembree4.so", "libembree4-4aef3270.so.4", "libtbb-dcf63f8c.so.12"];

fn main() {
    println!("cargo:rerun-if-env-changed=IPT_EMBREE_LIB");
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let src =
        std::env::var_os("IPT_EMBREE_LIB").map(PathBuf::from).unwrap_or_else(|| manifest.join("../deps/embree/lib"));
    for f in FILES {
        let p = src.join(f);
        println!("cargo:rerun-if-changed={}", p.display());
        if !p.exists() {
            panic!(
                "Embree 4.4 library not found at {} (run scripts/setup, or set IPT_EMBREE_LIB to a folder holding {:?})",
                p.display(),
                FILES
            );
        }
    }
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("embree");
    std::fs::create_dir_all(&out).expect("create OUT_DIR/embree");
    for f in FILES {
        let dst = out.join(f);
        let _ = std::fs::remove_file(&dst);
        let target = std::fs::canonicalize(src.join(f)).expect("canonicalize embree lib");
        std::os::unix::fs::symlink(&target, &dst).expect("symlink embree lib into OUT_DIR");
    }
    println!("cargo:rustc-link-search=native={}", out.display());
    println!("cargo:rustc-link-lib=dylib=embree4");
}
