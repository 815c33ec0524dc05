//! Stage manifests (`output.path/<stage>/manifest.json`, format `ipt-manifest/1`): what a finished stage
//! was computed from (SHA-256 of its config section and of its inputs) and what it wrote (SHA-256 and size of
//! every output file). A stage without a manifest is unfinished; the manifest is written last, atomically.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::atomic_file::{AtomicWriteError, write_atomic};

/// The manifest format tag.
pub const MANIFEST_FORMAT: &str = "ipt-manifest/1";
/// The manifest's file name inside a stage directory.
pub const MANIFEST_FILE: &str = "manifest.json";

/// Errors reading inputs to hash or writing a manifest.
#[derive(Debug, thiserror::Error)]
pub enum ManifestError {
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
}

/// One output file: its content hash and size.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileDigest {
    pub sha256: String,
    pub bytes: u64,
}

/// A finished stage's record.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    pub stage: String,
    /// `pipeline` version that wrote it (informative).
    pub pipeline_version: String,
    /// SHA-256 of the stage's config section (canonical JSON, see [`crate::plan::Plan::stage_config`]).
    pub config_sha256: String,
    /// SHA-256 over `inputs`.
    pub inputs_sha256: String,
    /// Each input by name (`stage:<name>` = an upstream manifest's `outputs_sha256`, `file:<relative path>` =
    /// a scan file's content hash) → SHA-256.
    pub inputs: BTreeMap<String, String>,
    /// Output files, relative to `output.path`, → digest.
    pub outputs: BTreeMap<String, FileDigest>,
    /// SHA-256 over `outputs`: what downstream stages record as their input.
    pub outputs_sha256: String,
}

/// Why a stage must run (or that it need not).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Freshness {
    /// Manifest present, config and inputs unchanged, outputs intact.
    UpToDate,
    /// Must run; the reason is printed.
    Stale(String),
}

/// Lower-case hex SHA-256 of `bytes`.
#[must_use]
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    bytes.iter().fold(String::with_capacity(bytes.len() * 2), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// SHA-256 of a JSON value's canonical text (serde_json keeps struct field order and sorts maps built from
/// BTreeMaps; `json!` objects are sorted maps), so equal values hash equally.
#[must_use]
pub fn sha256_json(value: &serde_json::Value) -> String {
    sha256_hex(value.to_string().as_bytes())
}

/// SHA-256 and size of a file's content, streamed.
pub fn digest_file(path: &Path) -> Result<FileDigest, ManifestError> {
    let io = |source| ManifestError::Io { path: path.to_path_buf(), source };
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok(FileDigest { sha256: hex(&hasher.finalize()), bytes })
}

/// SHA-256 over a name → hash map (each entry as `name\0hash\n`, in key order).
#[must_use]
pub fn sha256_map<'a>(entries: impl IntoIterator<Item = (&'a String, &'a String)>) -> String {
    let mut hasher = Sha256::new();
    for (k, v) in entries {
        hasher.update(k.as_bytes());
        hasher.update([0]);
        hasher.update(v.as_bytes());
        hasher.update([b'\n']);
    }
    hex(&hasher.finalize())
}

/// Content hashes of every regular file under `dir` (recursively, skipping `exclude` and hidden entries),
/// keyed `file:<path relative to dir>` with `/` separators.
pub fn digest_tree(dir: &Path, exclude: Option<&Path>) -> Result<BTreeMap<String, String>, ManifestError> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|source| ManifestError::Io { path: d.clone(), source })?;
        for entry in entries {
            let entry = entry.map_err(|source| ManifestError::Io { path: d.clone(), source })?;
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') || exclude.is_some_and(|x| path.starts_with(x)) {
                continue;
            }
            let ft = entry.file_type().map_err(|source| ManifestError::Io { path: path.clone(), source })?;
            if ft.is_dir() {
                stack.push(path);
            } else if ft.is_file() || ft.is_symlink() && path.is_file() {
                let rel = path.strip_prefix(dir).unwrap_or(&path);
                let key: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
                out.insert(format!("file:{}", key.join("/")), digest_file(&path)?.sha256);
            }
        }
    }
    Ok(out)
}

impl Manifest {
    /// Builds a manifest for `stage` from its config hash, inputs and the output files (relative to `root`,
    /// which are hashed now).
    pub fn build(
        stage: &str,
        config_sha256: String,
        inputs: BTreeMap<String, String>,
        root: &Path,
        outputs: &[PathBuf],
    ) -> Result<Self, ManifestError> {
        let mut out = BTreeMap::new();
        for rel in outputs {
            out.insert(rel_key(rel), digest_file(&root.join(rel))?);
        }
        let outputs_sha256 = sha256_map(out.iter().map(|(k, d)| (k, &d.sha256)));
        Ok(Self {
            format: MANIFEST_FORMAT.to_owned(),
            stage: stage.to_owned(),
            pipeline_version: env!("CARGO_PKG_VERSION").to_owned(),
            config_sha256,
            inputs_sha256: sha256_map(&inputs),
            inputs,
            outputs: out,
            outputs_sha256,
        })
    }

    /// Reads `dir/manifest.json`; `None` when absent or unreadable (an unfinished or foreign stage dir).
    #[must_use]
    pub fn read(dir: &Path) -> Option<Self> {
        let text = std::fs::read_to_string(dir.join(MANIFEST_FILE)).ok()?;
        let m: Self = serde_json::from_str(&text).ok()?;
        (m.format == MANIFEST_FORMAT).then_some(m)
    }

    /// Writes `dir/manifest.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<(), ManifestError> {
        let text = serde_json::to_string_pretty(self).expect("manifest serialises (only strings and maps)");
        write_atomic(&dir.join(MANIFEST_FILE), text.as_bytes())?;
        Ok(())
    }

    /// Compares with what the stage would be computed from now, and checks that every recorded output is
    /// still there with its recorded size and content digest: a damaged artefact (truncated, a flipped byte)
    /// makes the stage rerun, and is never used. Re-hashing streams every output once per run (SHA-256 at
    /// several hundred MB/s: about a second for a house's photo cache).
    #[must_use]
    pub fn freshness(&self, config_sha256: &str, inputs: &BTreeMap<String, String>, root: &Path) -> Freshness {
        if self.config_sha256 != config_sha256 {
            return Freshness::Stale("its config section changed".to_owned());
        }
        if self.inputs != *inputs {
            let changed: Vec<&str> = inputs
                .iter()
                .filter(|(k, v)| self.inputs.get(*k) != Some(*v))
                .map(|(k, _)| k.as_str())
                .chain(self.inputs.keys().filter(|k| !inputs.contains_key(*k)).map(String::as_str))
                .take(3)
                .collect();
            return Freshness::Stale(format!("its inputs changed ({})", changed.join(", ")));
        }
        for (rel, d) in &self.outputs {
            match std::fs::metadata(root.join(rel)) {
                Ok(m) if m.len() == d.bytes => {}
                Ok(m) => {
                    return Freshness::Stale(format!(
                        "output {rel} is damaged ({} bytes, the manifest records {})",
                        m.len(),
                        d.bytes
                    ));
                }
                Err(_) => return Freshness::Stale(format!("output {rel} is missing")),
            }
            match digest_file(&root.join(rel)) {
                Ok(now) if now.sha256 == d.sha256 => {}
                Ok(_) => return Freshness::Stale(format!("output {rel} is damaged (its content digest changed)")),
                Err(e) => return Freshness::Stale(format!("output {rel} is unreadable ({e})")),
            }
        }
        Freshness::UpToDate
    }
}

fn rel_key(rel: &Path) -> String {
    let parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_matches_the_fips_test_vector() {
        // FIPS 180-2, appendix B.1.
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }

    #[test]
    fn json_hash_ignores_key_order_of_maps() {
        let a: serde_json::Value = serde_json::from_str(r#"{"a": 1, "b": [1, 2]}"#).unwrap();
        let b: serde_json::Value = serde_json::from_str(r#"{"b": [1, 2], "a": 1}"#).unwrap();
        assert_eq!(sha256_json(&a), sha256_json(&b));
        let c: serde_json::Value = serde_json::from_str(r#"{"b": [2, 1], "a": 1}"#).unwrap();
        assert_ne!(sha256_json(&a), sha256_json(&c));
    }

    #[test]
    fn manifest_round_trips_and_detects_each_kind_of_change() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir(root.join("s")).unwrap();
        std::fs::write(root.join("s/a.bin"), b"hello").unwrap();
        let inputs: BTreeMap<String, String> = [("stage:ingest".to_owned(), "00".to_owned())].into();
        let m = Manifest::build("s", "cfg".into(), inputs.clone(), root, &[PathBuf::from("s/a.bin")]).unwrap();
        assert_eq!(m.outputs["s/a.bin"], FileDigest { sha256: sha256_hex(b"hello"), bytes: 5 });
        m.write(&root.join("s")).unwrap();
        let back = Manifest::read(&root.join("s")).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.freshness("cfg", &inputs, root), Freshness::UpToDate);
        assert!(matches!(back.freshness("other", &inputs, root), Freshness::Stale(r) if r.contains("config")));
        let changed: BTreeMap<String, String> = [("stage:ingest".to_owned(), "01".to_owned())].into();
        assert!(matches!(back.freshness("cfg", &changed, root), Freshness::Stale(r) if r.contains("stage:ingest")));
        std::fs::write(root.join("s/a.bin"), b"hello!").unwrap();
        assert!(matches!(back.freshness("cfg", &inputs, root), Freshness::Stale(r) if r.contains("damaged")));
        // Same size, one byte changed: the content digest sees it.
        std::fs::write(root.join("s/a.bin"), b"hellp").unwrap();
        assert!(
            matches!(back.freshness("cfg", &inputs, root), Freshness::Stale(r) if r.contains("content digest changed"))
        );
        std::fs::remove_file(root.join("s/a.bin")).unwrap();
        assert!(matches!(back.freshness("cfg", &inputs, root), Freshness::Stale(r) if r.contains("missing")));
    }

    #[test]
    fn tree_digest_sees_content_changes_and_skips_hidden_and_excluded() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir_all(root.join("sub")).unwrap();
        std::fs::create_dir_all(root.join("out")).unwrap();
        std::fs::write(root.join("sub/x.txt"), b"1").unwrap();
        std::fs::write(root.join(".hidden"), b"1").unwrap();
        std::fs::write(root.join("out/y"), b"1").unwrap();
        let a = digest_tree(root, Some(&root.join("out"))).unwrap();
        assert_eq!(a.keys().collect::<Vec<_>>(), ["file:sub/x.txt"]);
        std::fs::write(root.join("sub/x.txt"), b"2").unwrap();
        let b = digest_tree(root, Some(&root.join("out"))).unwrap();
        assert_ne!(a, b);
    }
}
