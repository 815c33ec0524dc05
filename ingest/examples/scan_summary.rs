//! Loads a scan directory and prints a one-screen summary (format, triangles, objects, views, unseen objects),
//! or the error. Handy for checking a user's data before a long run.
//!
//! Usage: `cargo run -p ingest --example scan_summary -- DIR [segment|category|material|obj_group|obj_material]`

use std::path::PathBuf;

use ingest::{GroupBy, ScanFormat, load_scan, objects_seen_by_no_camera};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir: PathBuf = args.next().ok_or("usage: scan_summary DIR [GROUP_BY]")?.into();
    let group_by: GroupBy = match args.next() {
        Some(g) => serde_json::from_str(&format!("\"{g}\""))?,
        None => GroupBy::default(),
    };
    let format = ingest::scan::detect_format(&dir)?;
    let scan = load_scan(&dir, ScanFormat::Auto, group_by)?;
    println!("format {format:?}, {} vertices, {} triangles", scan.mesh.positions.len(), scan.mesh.triangles.len());
    println!("{} objects (grouped by {group_by:?}):", scan.objects.len());
    for o in &scan.objects {
        println!("  {:>8} {:>9} triangles  {}", o.id, o.triangles, o.label.as_deref().unwrap_or("-"));
    }
    println!("{} views", scan.views.len());
    for v in scan.views.iter().take(5) {
        let c = &v.camera;
        println!("  {} {}x{} fx {:.2} -> {}", v.name, c.width, c.height, c.intrinsics.fx, v.image_path.display());
    }
    println!("objects seen by no camera: {:?}", objects_seen_by_no_camera(&scan));
    Ok(())
}
