//! The Embree device configuration: the string given to `rtcNewDevice`, read from the environment variable
//! [`CONFIG_ENV`] (`IPT_EMBREE_CONFIG`) and checked before Embree sees it.
//!
//! Embree picks its traversal and intersection kernels by the processor's instruction set (SSE2, SSE4.2,
//! AVX, AVX2, AVX-512). Each kernel rounds a little differently, so hit distances and barycentrics agree
//! across processors only to within float rounding, not bit for bit. Forcing a lower instruction set
//! (`max_isa=sse4.2`, `max_isa=avx2`) reproduces on one machine what another processor would compute, which
//! is how `make test` checks that no test depends on the processor it happens to run on.
//!
//! Accepted: a comma-separated list of Embree's own `key=value` items. The keys are a subset of Embree's
//! device configuration: `isa` and `max_isa` (values `sse2`, `sse4.2`, `avx`, `avx2`, `avx512`), `threads`,
//! `user_threads`, `set_affinity`, `start_threads`, `verbose`, `frequency_level` (`simd128`, `simd256`,
//! `simd512`) and `hugepages`. Anything else is refused: Embree ignores what it does not understand, so a
//! misspelt key would otherwise silently run the native kernels. `isa=X` (which *sets* the kernels) is refused
//! when this processor lacks X, because Embree would then execute instructions the processor does not have;
//! `max_isa=X` only caps the kernels and is always safe.

use super::EmbreeError;
use std::ffi::CString;

/// The environment variable holding the Embree device configuration (empty or unset: Embree's defaults, i.e.
/// the best kernels for this processor).
pub const CONFIG_ENV: &str = "IPT_EMBREE_CONFIG";

/// The instruction-set names accepted for `isa` and `max_isa`, lowest first.
pub const ISA_NAMES: [&str; 5] = ["sse2", "sse4.2", "avx", "avx2", "avx512"];

/// Keys whose value is a non-negative integer.
const INTEGER_KEYS: [&str; 5] = ["threads", "user_threads", "set_affinity", "start_threads", "verbose"];

/// Reads [`CONFIG_ENV`] and checks it ([`parse`]). Unset and empty both mean Embree's defaults.
pub fn from_env() -> Result<CString, EmbreeError> {
    match std::env::var(CONFIG_ENV) {
        Ok(value) => parse(&value),
        Err(std::env::VarError::NotPresent) => Ok(CString::default()),
        Err(std::env::VarError::NotUnicode(_)) => Err(bad("(not UTF-8)", "the value is not UTF-8")),
    }
}

/// The configuration string as Embree receives it, or an error naming the offending item.
pub fn parse(value: &str) -> Result<CString, EmbreeError> {
    let mut items = Vec::new();
    for item in value.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let Some((key, val)) = item.split_once('=').map(|(k, v)| (k.trim(), v.trim())) else {
            return Err(bad(value, &format!("item {item:?} is not key=value")));
        };
        match key {
            "isa" | "max_isa" => {
                if !ISA_NAMES.contains(&val) {
                    return Err(bad(
                        value,
                        &format!("{key}={val}: known instruction sets are {}", ISA_NAMES.join(", ")),
                    ));
                }
                if key == "isa" && !cpu_supports(val) {
                    return Err(bad(
                        value,
                        &format!("isa={val}: this processor lacks {val} (max_isa={val} caps the kernels safely)"),
                    ));
                }
            }
            "frequency_level" => {
                if !["simd128", "simd256", "simd512"].contains(&val) {
                    return Err(bad(value, &format!("frequency_level={val}: expected simd128, simd256 or simd512")));
                }
            }
            "hugepages" => {
                if !["0", "1"].contains(&val) {
                    return Err(bad(value, &format!("hugepages={val}: expected 0 or 1")));
                }
            }
            k if INTEGER_KEYS.contains(&k) => {
                if val.is_empty() || !val.bytes().all(|b| b.is_ascii_digit()) || val.len() > 6 {
                    return Err(bad(value, &format!("{key}={val}: expected a non-negative integer")));
                }
            }
            _ => return Err(bad(value, &format!("unknown key {key:?}"))),
        }
        items.push(format!("{key}={val}"));
    }
    // Every accepted item is ASCII without NUL, so the conversion cannot fail.
    CString::new(items.join(",")).map_err(|_| bad(value, "contains a NUL byte"))
}

fn bad(value: &str, reason: &str) -> EmbreeError {
    EmbreeError::Config { var: CONFIG_ENV, value: value.to_owned(), reason: reason.to_owned() }
}

/// Whether this processor implements instruction set `isa` as Embree's kernels of that name use it.
fn cpu_supports(isa: &str) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        match isa {
            "sse2" => has!("sse2"),
            "sse4.2" => has!("sse4.2"),
            "avx" => has!("avx"),
            // Embree's AVX2 kernels also use FMA3, BMI1/2 and LZCNT.
            "avx2" => has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt"),
            // Embree's AVX-512 kernels are its Skylake-X set.
            "avx512" => has!("avx512f") && has!("avx512dq") && has!("avx512cd") && has!("avx512bw") && has!("avx512vl"),
            _ => false,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = isa;
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_embree_items_and_normalises_spacing() {
        assert_eq!(parse("").unwrap().to_str().unwrap(), "");
        assert_eq!(parse(" max_isa = sse4.2 , threads=2 ").unwrap().to_str().unwrap(), "max_isa=sse4.2,threads=2");
        assert_eq!(parse("isa=sse2").unwrap().to_str().unwrap(), "isa=sse2");
        for isa in ISA_NAMES {
            assert!(parse(&format!("max_isa={isa}")).is_ok(), "{isa}");
        }
    }

    #[test]
    fn refuses_what_embree_would_silently_ignore() {
        for (value, needle) in [
            ("maxisa=avx2", "unknown key"),
            ("max_isa=avx3", "known instruction sets"),
            ("max_isa", "not key=value"),
            ("threads=-1", "non-negative integer"),
            ("frequency_level=fast", "simd128"),
        ] {
            let e = parse(value).unwrap_err().to_string();
            assert!(e.contains(CONFIG_ENV) && e.contains(needle), "{value}: {e}");
        }
    }

    #[test]
    fn isa_beyond_this_processor_is_refused() {
        for isa in ISA_NAMES {
            assert_eq!(parse(&format!("isa={isa}")).is_ok(), cpu_supports(isa), "{isa}");
        }
    }
}
