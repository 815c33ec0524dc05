//! Safe wrapper over the Embree 4 FFI: one device, one scene holding one triangle geometry, single-ray
//! closest-hit and occlusion queries. This module is the only place in the workspace with `unsafe`.
//!
//! Every handle is checked for null and every call that can fail is followed by `rtcGetDeviceError`.
//! After `commit`, Embree documents scenes as safe to query concurrently from any number of threads, which is
//! what makes [`TriangleScene`] `Send + Sync`.

pub mod config;
mod ffi;
#[cfg(feature = "ray-log")]
pub mod ray_log;

use glam::Vec3;
use std::ffi::{CStr, CString};

/// An Embree failure, with the operation that failed and Embree's own message.
#[derive(Debug, thiserror::Error)]
pub enum EmbreeError {
    #[error("embree: {op} failed: {message} (error code {code})")]
    Call { op: &'static str, code: u32, message: String },
    #[error("embree: {op} returned a null handle")]
    Null { op: &'static str },
    #[error("embree: mesh has {0} triangles; Embree primitive ids are 32-bit")]
    TooLarge(usize),
    #[error("embree: triangle {tri} references vertex {index} but the mesh has {vertices} vertices")]
    IndexOutOfRange { tri: usize, index: u32, vertices: usize },
    #[error("embree: {var}={value:?}: {reason}")]
    Config { var: &'static str, value: String, reason: String },
}

/// What the Embree device in use is: the configuration it was created with (from
/// [`config::CONFIG_ENV`]), Embree's version and the widest ray packet its active kernels support natively
/// (4 for SSE, 8 for AVX/AVX2, 16 for AVX-512): the instruction set that decides how hits round.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceInfo {
    pub config: String,
    pub version: u32,
    pub simd_width: u32,
}

impl std::fmt::Display for DeviceInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.version;
        let cfg = if self.config.is_empty() { "native" } else { &self.config };
        write!(f, "Embree {}.{}.{} ({cfg}, {}-wide kernels)", v / 10000, v / 100 % 100, v % 100, self.simd_width)
    }
}

/// The device that [`TriangleScene::new`] creates, described: the configuration from the environment.
pub fn device_info() -> Result<DeviceInfo, EmbreeError> {
    Device::new()?.info()
}

/// A device created with the given configuration (checked by [`config::parse`]), described.
pub fn device_info_with(config: &str) -> Result<DeviceInfo, EmbreeError> {
    Device::with_config(config::parse(config)?)?.info()
}

/// A closest hit: distance along the (unnormalised) ray direction, triangle index, barycentrics (u, v) of
/// vertices 1 and 2, and Embree's unnormalised geometric normal `(v1 - v0) x (v2 - v0)` up to sign convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    pub t: f32,
    pub prim_id: u32,
    pub u: f32,
    pub v: f32,
    pub ng: Vec3,
}

struct Device(ffi::RTCDevice, CString);

impl Device {
    /// A device configured by the environment ([`config::from_env`]).
    fn new() -> Result<Self, EmbreeError> {
        Self::with_config(config::from_env()?)
    }

    /// An empty configuration lets Embree pick the instruction set and thread count itself; it builds BVHs
    /// with TBB threads, while queries run on the caller's (rayon) threads.
    fn with_config(cfg: CString) -> Result<Self, EmbreeError> {
        // SAFETY: the pointer is a valid NUL-terminated C string for the duration of the call.
        let raw = unsafe { ffi::rtcNewDevice(cfg.as_ptr()) };
        if raw.is_null() {
            // rtcGetDeviceError(NULL) reports errors of device creation.
            // SAFETY: null is the documented argument for device-creation errors.
            let code = unsafe { ffi::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(EmbreeError::Call { op: "rtcNewDevice", code, message: "device creation failed".into() });
        }
        Ok(Device(raw, cfg))
    }

    fn info(&self) -> Result<DeviceInfo, EmbreeError> {
        // SAFETY: self.0 is a live device handle; the properties queried exist in Embree 4.4.
        let prop = |p| unsafe { ffi::rtcGetDeviceProperty(self.0, p) };
        let version = prop(ffi::RTC_DEVICE_PROPERTY_VERSION);
        let simd_width = if prop(ffi::RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) != 0 {
            16
        } else if prop(ffi::RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0 {
            8
        } else {
            4
        };
        self.check("rtcGetDeviceProperty")?;
        Ok(DeviceInfo {
            config: self.1.to_string_lossy().into_owned(),
            version: u32::try_from(version).unwrap_or(0),
            simd_width,
        })
    }

    /// Turns a pending device error into `Err`, naming the operation.
    fn check(&self, op: &'static str) -> Result<(), EmbreeError> {
        // SAFETY: self.0 is a live device handle.
        let code = unsafe { ffi::rtcGetDeviceError(self.0) };
        if code == ffi::RTC_ERROR_NONE {
            return Ok(());
        }
        // SAFETY: Embree returns a NUL-terminated string owned by the device, or null.
        let message = unsafe {
            let p = ffi::rtcGetDeviceLastErrorMessage(self.0);
            if p.is_null() { String::from("(no message)") } else { CStr::from_ptr(p).to_string_lossy().into_owned() }
        };
        Err(EmbreeError::Call { op, code, message })
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: we own one reference to this device.
        unsafe { ffi::rtcReleaseDevice(self.0) }
    }
}

/// A committed Embree scene of one triangle mesh. Primitive id = index into the triangle list given to `new`.
pub struct TriangleScene {
    scene: ffi::RTCScene,
    device: Device,
    triangles: usize,
}

impl std::fmt::Debug for TriangleScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleScene").field("triangles", &self.triangles).finish()
    }
}

// SAFETY: a committed scene is immutable and Embree documents rtcIntersect1/rtcOccluded1 as thread-safe on
// it; the device is only used for error queries after construction.
#[allow(unsafe_code)]
unsafe impl Send for TriangleScene {}
#[allow(unsafe_code)]
unsafe impl Sync for TriangleScene {}

impl TriangleScene {
    /// Builds and commits a scene (robust traversal, high-quality BVH). Indices are checked against the vertex
    /// count before Embree sees them.
    pub fn new(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, EmbreeError> {
        if triangles.len() > (u32::MAX - 1) as usize {
            return Err(EmbreeError::TooLarge(triangles.len()));
        }
        for (tri, t) in triangles.iter().enumerate() {
            for &index in t {
                if index as usize >= positions.len() {
                    return Err(EmbreeError::IndexOutOfRange { tri, index, vertices: positions.len() });
                }
            }
        }
        let device = Device::new()?;
        // SAFETY: device is live; every handle is checked before use and released on every path.
        unsafe {
            let scene = ffi::rtcNewScene(device.0);
            if scene.is_null() {
                device.check("rtcNewScene")?;
                return Err(EmbreeError::Null { op: "rtcNewScene" });
            }
            // From here on `out` owns the scene, so early returns release it.
            let out = TriangleScene { scene, device, triangles: triangles.len() };
            // Robust mode: no missed hits on shared edges (closed rooms must not leak light).
            ffi::rtcSetSceneFlags(scene, ffi::RTC_SCENE_FLAG_ROBUST);
            ffi::rtcSetSceneBuildQuality(scene, ffi::RTC_BUILD_QUALITY_HIGH);
            out.device.check("rtcSetSceneFlags")?;

            let geom = ffi::rtcNewGeometry(out.device.0, ffi::RTC_GEOMETRY_TYPE_TRIANGLE);
            if geom.is_null() {
                out.device.check("rtcNewGeometry")?;
                return Err(EmbreeError::Null { op: "rtcNewGeometry" });
            }
            let result = (|| {
                let vb = ffi::rtcSetNewGeometryBuffer(
                    geom,
                    ffi::RTC_BUFFER_TYPE_VERTEX,
                    0,
                    ffi::RTC_FORMAT_FLOAT3,
                    12,
                    positions.len(),
                ) as *mut f32;
                out.device.check("rtcSetNewGeometryBuffer(vertex)")?;
                if vb.is_null() && !positions.is_empty() {
                    return Err(EmbreeError::Null { op: "rtcSetNewGeometryBuffer(vertex)" });
                }
                for (i, p) in positions.iter().enumerate() {
                    *vb.add(3 * i) = p.x;
                    *vb.add(3 * i + 1) = p.y;
                    *vb.add(3 * i + 2) = p.z;
                }
                let ib = ffi::rtcSetNewGeometryBuffer(
                    geom,
                    ffi::RTC_BUFFER_TYPE_INDEX,
                    0,
                    ffi::RTC_FORMAT_UINT3,
                    12,
                    triangles.len(),
                ) as *mut u32;
                out.device.check("rtcSetNewGeometryBuffer(index)")?;
                if ib.is_null() && !triangles.is_empty() {
                    return Err(EmbreeError::Null { op: "rtcSetNewGeometryBuffer(index)" });
                }
                for (i, t) in triangles.iter().enumerate() {
                    *ib.add(3 * i) = t[0];
                    *ib.add(3 * i + 1) = t[1];
                    *ib.add(3 * i + 2) = t[2];
                }
                ffi::rtcCommitGeometry(geom);
                out.device.check("rtcCommitGeometry")?;
                let id = ffi::rtcAttachGeometry(out.scene, geom);
                out.device.check("rtcAttachGeometry")?;
                if id == ffi::RTC_INVALID_GEOMETRY_ID {
                    return Err(EmbreeError::Null { op: "rtcAttachGeometry" });
                }
                Ok(())
            })();
            // The scene holds its own reference once attached; ours is released either way.
            ffi::rtcReleaseGeometry(geom);
            result?;
            ffi::rtcCommitScene(out.scene);
            out.device.check("rtcCommitScene")?;
            Ok(out)
        }
    }

    /// The device this scene was built on.
    pub fn device_info(&self) -> Result<DeviceInfo, EmbreeError> {
        self.device.info()
    }

    /// Number of triangles (primitive ids are `0..triangles()`).
    #[must_use]
    pub fn triangles(&self) -> usize {
        self.triangles
    }

    /// Closest hit along `org + t·dir` for `t` in `[tnear, tfar]`, or `None`.
    #[inline]
    #[must_use]
    pub fn intersect(&self, org: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> Option<RayHit> {
        #[cfg(feature = "ray-log")]
        ray_log::log(org, dir, tnear, tfar, false);
        let mut rh = ffi::RTCRayHit {
            ray: ray(org, dir, tnear, tfar),
            hit: ffi::RTCHit {
                geom_id: ffi::RTC_INVALID_GEOMETRY_ID,
                inst_id: [ffi::RTC_INVALID_GEOMETRY_ID],
                ..Default::default()
            },
        };
        // SAFETY: the scene is committed; `rh` is a properly sized, 16-byte aligned RTCRayHit; null args = defaults.
        unsafe { ffi::rtcIntersect1(self.scene, &mut rh, std::ptr::null_mut()) };
        (rh.hit.geom_id != ffi::RTC_INVALID_GEOMETRY_ID).then(|| RayHit {
            t: rh.ray.tfar,
            prim_id: rh.hit.prim_id,
            u: rh.hit.u,
            v: rh.hit.v,
            ng: Vec3::new(rh.hit.ng_x, rh.hit.ng_y, rh.hit.ng_z),
        })
    }

    /// True when anything blocks `org + t·dir` for `t` in `[tnear, tfar]`.
    #[inline]
    #[must_use]
    pub fn occluded(&self, org: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> bool {
        #[cfg(feature = "ray-log")]
        ray_log::log(org, dir, tnear, tfar, true);
        let mut r = ray(org, dir, tnear, tfar);
        // SAFETY: the scene is committed; `r` is a properly sized, 16-byte aligned RTCRay.
        unsafe { ffi::rtcOccluded1(self.scene, &mut r, std::ptr::null_mut()) };
        r.tfar == f32::NEG_INFINITY
    }
}

/// Asks the processor to start loading the cache line holding `*r` into all cache levels, without waiting
/// for it: a pure performance hint with no effect on any result (a no-op off x86-64). The integrator uses it
/// for the record of a hit triangle, so that the line arrives while the previous vertex's shadow ray is traced.
#[inline]
pub fn prefetch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: PREFETCHT0 belongs to SSE, which every x86-64 processor implements; it never faults, and `r` is
    // a valid reference anyway.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((r as *const T).cast())
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}

#[inline]
fn ray(org: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> ffi::RTCRay {
    ffi::RTCRay {
        org_x: org.x,
        org_y: org.y,
        org_z: org.z,
        tnear,
        dir_x: dir.x,
        dir_y: dir.y,
        dir_z: dir.z,
        time: 0.0,
        tfar,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

impl Drop for TriangleScene {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the scene; the device outlives it (dropped after this body).
        unsafe { ffi::rtcReleaseScene(self.scene) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_triangle() -> TriangleScene {
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        TriangleScene::new(&p, &[[0, 1, 2]]).expect("scene")
    }

    #[test]
    fn intersects_known_triangle() {
        let s = unit_triangle();
        let h = s.intersect(Vec3::new(0.25, 0.25, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).expect("hit");
        assert_eq!(h.prim_id, 0);
        // Embree's kernels differ by instruction set (SSE4.2 gives 2.0, AVX2 1.9999999): a hit distance is
        // exact only to a few ulps of t. 4 ulps of 2.0 = 9.5e-7; u and v are within 4 ulps of 0.25 likewise.
        let ulps = |x: f32| 4.0 * f32::EPSILON * x.abs();
        assert!((h.t - 2.0).abs() <= ulps(2.0), "{h:?}");
        assert!((h.u - 0.25).abs() <= ulps(1.0) && (h.v - 0.25).abs() <= ulps(1.0), "{h:?}");
        assert!(h.ng.cross(Vec3::Z).length() < 1e-6 && h.ng.z.abs() > 0.0, "{h:?}");
        // Misses outside the triangle and beyond tfar.
        assert!(s.intersect(Vec3::new(0.8, 0.8, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).is_none());
        assert!(s.intersect(Vec3::new(0.25, 0.25, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, 1.5).is_none());
    }

    #[test]
    fn occluded_agrees_with_intersect() {
        let s = unit_triangle();
        for i in 0..200 {
            let x = (i % 20) as f32 / 19.0 * 1.4 - 0.2;
            let y = (i / 20) as f32 / 9.0 * 1.4 - 0.2;
            let org = Vec3::new(x, y, 1.0);
            let dir = Vec3::new(0.01, -0.02, -1.0);
            for tfar in [0.5, 2.0] {
                let hit = s.intersect(org, dir, 0.0, tfar).is_some();
                assert_eq!(hit, s.occluded(org, dir, 0.0, tfar), "ray {i} tfar {tfar}");
            }
        }
    }

    #[test]
    fn rayhit_guard_word_is_not_overwritten() {
        // Embree writes the full 96-byte RTCRayHit; a guard word right after it must survive a hit.
        #[repr(C, align(16))]
        struct Guarded {
            rh: ffi::RTCRayHit,
            guard: [u32; 8],
        }
        let s = unit_triangle();
        let mut g = Guarded {
            rh: ffi::RTCRayHit {
                ray: ray(Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY),
                hit: ffi::RTCHit { geom_id: ffi::RTC_INVALID_GEOMETRY_ID, ..Default::default() },
            },
            guard: [0xDEAD_BEEF; 8],
        };
        // SAFETY: same contract as `intersect`; the struct is 16-byte aligned.
        #[allow(unsafe_code)]
        unsafe {
            ffi::rtcIntersect1(s.scene, &mut g.rh, std::ptr::null_mut())
        };
        assert_eq!(g.rh.hit.prim_id, 0);
        assert_eq!(g.rh.hit.geom_id, 0);
        assert_eq!(g.guard, [0xDEAD_BEEF; 8]);
    }

    #[test]
    fn device_configuration_selects_the_kernels() {
        let sse = device_info_with("max_isa=sse4.2").expect("SSE4.2 device");
        assert_eq!(sse.simd_width, 4, "{sse}");
        assert_eq!(sse.config, "max_isa=sse4.2");
        assert_eq!(sse.version / 100, 404, "Embree 4.4 expected: {sse}");
        let native = device_info_with("").expect("native device");
        #[cfg(target_arch = "x86_64")]
        {
            let expect = if std::arch::is_x86_feature_detected!("avx512f") {
                16
            } else if std::arch::is_x86_feature_detected!("avx") {
                8
            } else {
                4
            };
            assert_eq!(native.simd_width, expect, "{native}");
            if expect >= 8 {
                assert_eq!(device_info_with("max_isa=avx2").unwrap().simd_width, 8);
            }
        }
    }

    #[test]
    fn out_of_range_index_is_an_error() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let e = TriangleScene::new(&p, &[[0, 1, 7]]).unwrap_err();
        assert!(e.to_string().contains("vertex 7"), "{e}");
    }
}
