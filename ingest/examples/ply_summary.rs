//! Reads any PLY with our reader and prints what it read as JSON (see `common/ingest_summary.rs`); exits
//! non-zero with the error message on bad input.
//!
//! Usage: `cargo run -p ingest --example ply_summary -- FILE.ply`

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path: PathBuf = std::env::args_os().nth(1).ok_or("usage: ply_summary FILE.ply")?.into();
    let read = ingest::ply::read_ply(&path)?;
    println!("{}", ingest_summary::to_json(&read));
    Ok(())
}

#[path = "common/ingest_summary.rs"]
mod ingest_summary;
