//! Projects points given in OpenCV camera coordinates (x right, y down, z forward) through a camera read from a
//! COLMAP `cameras.txt`, printing pixels in OUR convention (pixel centres at integers; add 0.5 for COLMAP's).
//! Points behind the camera print `nan nan`.
//!
//! Usage: `cargo run -p ingest --example project -- cameras.txt CAMERA_ID < points.txt` (one `x y z` per line)

use std::io::{BufRead, Write};
use std::path::PathBuf;

use glam::{DMat4, DVec3};
use ingest::camera::Camera;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args_os().skip(1);
    let cameras: PathBuf = args.next().ok_or("usage: project cameras.txt CAMERA_ID < points")?.into();
    let id: u32 = args.next().ok_or("missing CAMERA_ID")?.to_string_lossy().parse()?;
    let cams = ingest::colmap::read_cameras(&cameras)?;
    let c = cams.get(&id).ok_or_else(|| format!("camera {id} not in {}", cameras.display()))?;
    let camera = Camera {
        width: c.width,
        height: c.height,
        intrinsics: c.intrinsics,
        distortion: c.distortion,
        cam_to_world: DMat4::IDENTITY,
    };
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for (k, line) in std::io::stdin().lock().lines().enumerate() {
        let line = line?;
        let v: Vec<f64> = line.split_ascii_whitespace().map(str::parse).collect::<Result<_, _>>()?;
        let [x, y, z] = v[..] else { return Err(format!("stdin line {}: expected x y z", k + 1).into()) };
        match camera.project_opencv(DVec3::new(x, y, z)) {
            Some(p) => writeln!(out, "{:.17e} {:.17e}", p.x, p.y)?,
            None => writeln!(out, "nan nan")?,
        }
    }
    Ok(())
}
