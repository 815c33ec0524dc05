//! Undistorts one photo with the same path as the pipeline (`ingest::photo::prepare_view`: linearise, OpenCV
//! undistortion with alpha = 0, optional downscale) and writes the result with the cache writer.
//!
//! Usage: `undistort IN OUT.exr fx fy cx cy k1 k2 p1 p2 k3 [downscale]`
//!
//! Writes `OUT.exr` (R, G, B linear, mask) and `OUT.json` (manifest with the new pinhole camera), and prints
//! the new intrinsics as JSON on stdout. Used by tests/validation/test_undistort.py and test_chessboard.py.

use std::error::Error;
use std::path::Path;

use glam::DMat4;
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::{PhotoOptions, prepare_view, read_image, write_cached};

fn main() {
    if let Err(e) = run() {
        eprintln!("undistort: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 11 && args.len() != 12 {
        return Err("usage: undistort IN OUT.exr fx fy cx cy k1 k2 p1 p2 k3 [downscale]".into());
    }
    let input = Path::new(&args[0]);
    let output = Path::new(&args[1]);
    let num: Vec<f64> = args[2..11].iter().map(|a| a.parse::<f64>()).collect::<Result<_, _>>()?;
    let downscale = match args.get(11) {
        Some(s) => s.parse::<u32>()?,
        None => 1,
    };
    let (width, height) = read_image(input)?.size();
    let camera = Camera {
        width,
        height,
        intrinsics: Intrinsics { fx: num[0], fy: num[1], cx: num[2], cy: num[3] },
        distortion: Distortion { k1: num[4], k2: num[5], p1: num[6], p2: num[7], k3: num[8], ..Default::default() },
        cam_to_world: DMat4::IDENTITY,
    };
    let opts = PhotoOptions { downscale, ..Default::default() };
    let (new_camera, image) = prepare_view(input, &camera, &opts)?;
    let dir = output.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = output.file_stem().ok_or("OUT.exr has no file name")?.to_string_lossy();
    if output.extension().and_then(|e| e.to_str()) != Some("exr") {
        return Err("OUT must end in .exr".into());
    }
    write_cached(dir, &name, &new_camera, &image)?;
    println!("{}", serde_json::to_string(&new_camera.intrinsics)?);
    Ok(())
}
