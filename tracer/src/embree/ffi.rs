//! Hand-written bindings to the dozen Embree 4.4 entry points the tracer uses.
//!
//! Written against `rtcore_device.h`, `rtcore_scene.h`, `rtcore_geometry.h`, `rtcore_buffer.h` and
//! `rtcore_ray.h` of Embree 4.4.0 as built in the PyPI wheel `embreex==4.4.0.post1`. That build has
//! `RTC_MAX_INSTANCE_LEVEL_COUNT = 1` and instance arrays enabled, so `RTCHit` ends with `instPrimID` and
//! `RTCRayHit` is 96 bytes; the 80-byte layout of embree4-sys would let Embree write past every ray
//! (`../shared/notes/embree.md`). The `const` assertions below pin every size and alignment.

use std::ffi::{c_char, c_uint, c_void};

pub type RTCDevice = *mut c_void;
pub type RTCScene = *mut c_void;
pub type RTCGeometry = *mut c_void;

pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

// enum RTCError
pub const RTC_ERROR_NONE: u32 = 0;

// enum RTCDeviceProperty (rtcore_device.h)
pub const RTC_DEVICE_PROPERTY_VERSION: u32 = 0;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED: u32 = 33;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED: u32 = 34;

// enum RTCGeometryType
pub const RTC_GEOMETRY_TYPE_TRIANGLE: u32 = 0;

// enum RTCBufferType
pub const RTC_BUFFER_TYPE_INDEX: u32 = 0;
pub const RTC_BUFFER_TYPE_VERTEX: u32 = 1;

// enum RTCFormat
pub const RTC_FORMAT_UINT3: u32 = 0x5003;
pub const RTC_FORMAT_FLOAT3: u32 = 0x9003;

// enum RTCBuildQuality
pub const RTC_BUILD_QUALITY_HIGH: u32 = 2;

// enum RTCSceneFlags
pub const RTC_SCENE_FLAG_ROBUST: u32 = 1 << 2;

/// `struct RTCRay` (rtcore_ray.h), 16-byte aligned.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCRay {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: c_uint,
    pub id: c_uint,
    pub flags: c_uint,
}

/// `struct RTCHit` with `RTC_MAX_INSTANCE_LEVEL_COUNT == 1` and `RTC_GEOMETRY_INSTANCE_ARRAY` on.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCHit {
    pub ng_x: f32,
    pub ng_y: f32,
    pub ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub prim_id: c_uint,
    pub geom_id: c_uint,
    pub inst_id: [c_uint; 1],
    pub inst_prim_id: [c_uint; 1],
}

/// `struct RTCRayHit`.
#[repr(C, align(16))]
#[derive(Debug, Clone, Copy, Default)]
pub struct RTCRayHit {
    pub ray: RTCRay,
    pub hit: RTCHit,
}

const _: () = assert!(std::mem::size_of::<RTCRay>() == 48);
const _: () = assert!(std::mem::align_of::<RTCRay>() == 16);
const _: () = assert!(std::mem::size_of::<RTCHit>() == 48);
const _: () = assert!(std::mem::align_of::<RTCHit>() == 16);
const _: () = assert!(std::mem::size_of::<RTCRayHit>() == 96);
const _: () = assert!(std::mem::align_of::<RTCRayHit>() == 16);
const _: () = assert!(std::mem::offset_of!(RTCRayHit, hit) == 48);
const _: () = assert!(std::mem::offset_of!(RTCHit, prim_id) == 20);
const _: () = assert!(std::mem::offset_of!(RTCHit, inst_prim_id) == 32);

#[link(name = "embree4")]
unsafe extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceError(device: RTCDevice) -> u32;
    pub fn rtcGetDeviceLastErrorMessage(device: RTCDevice) -> *const c_char;
    pub fn rtcGetDeviceProperty(device: RTCDevice, prop: u32) -> isize;

    pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
    pub fn rtcReleaseScene(scene: RTCScene);
    pub fn rtcSetSceneFlags(scene: RTCScene, flags: u32);
    pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: u32);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    pub fn rtcCommitScene(scene: RTCScene);

    pub fn rtcNewGeometry(device: RTCDevice, kind: u32) -> RTCGeometry;
    pub fn rtcReleaseGeometry(geometry: RTCGeometry);
    pub fn rtcSetNewGeometryBuffer(
        geometry: RTCGeometry,
        kind: u32,
        slot: c_uint,
        format: u32,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    pub fn rtcCommitGeometry(geometry: RTCGeometry);

    /// `args` may be null (defaults).
    pub fn rtcIntersect1(scene: RTCScene, rayhit: *mut RTCRayHit, args: *mut c_void);
    /// `args` may be null (defaults). Sets `ray.tfar = -inf` when occluded.
    pub fn rtcOccluded1(scene: RTCScene, ray: *mut RTCRay, args: *mut c_void);
}
