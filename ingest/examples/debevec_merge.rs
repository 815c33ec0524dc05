//! Recovers a camera response from an exposure bracket with OpenCV's CalibrateDebevec and merges the bracket
//! with MergeDebevec (`ingest::photo::{recover_response, merge_bracket}`).
//!
//! Usage: `debevec_merge OUT.exr IMG1 TIME1 IMG2 TIME2 ...` (times in seconds)
//!
//! Writes `OUT.exr` (R, G, B radiance, mask) and prints the response curve (256 RGB rows) as JSON on stdout.
//! Used by tests/validation/test_debevec.py.

use std::error::Error;
use std::path::{Path, PathBuf};

use ingest::photo::response::bracket;
use ingest::photo::{merge_bracket, recover_response, write_exr};

fn main() {
    if let Err(e) = run() {
        eprintln!("debevec_merge: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 5 || args.len() % 2 == 0 {
        return Err("usage: debevec_merge OUT.exr IMG1 TIME1 IMG2 TIME2 ...".into());
    }
    let output = Path::new(&args[0]);
    let mut paths = Vec::new();
    let mut times = Vec::new();
    for pair in args[1..].chunks_exact(2) {
        paths.push(PathBuf::from(&pair[0]));
        times.push(pair[1].parse::<f64>().map_err(|e| format!("{}: bad time {:?}: {e}", pair[0], pair[1]))?);
    }
    let exposures = bracket(&paths, &times);
    let curve = recover_response(&exposures)?;
    let merged = merge_bracket(&exposures, &curve)?;
    write_exr(output, &merged)?;
    println!("{}", serde_json::to_string(&curve)?);
    Ok(())
}
