//! What each stage writes into `output.path/<stage>/` and how later stages (and `pipeline render`,
//! `pipeline export`) read it back: file names, format tags, the serialised types and their readers. The
//! stages ([`crate::stages`]) write these files and read each other's only through this module.

pub mod checkpoint;
pub mod ingest;
pub mod object;
pub mod preprocess;
pub mod triangle;
