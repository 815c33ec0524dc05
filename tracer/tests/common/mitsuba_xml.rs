//! A minimal reader for the subset of Mitsuba 3 scene XML used by Bitterli's Cornell box: `rectangle` and
//! `cube` shapes with `to_world` matrices, `diffuse` (optionally inside `twosided`) reflectance, `area`
//! emitters with RGB radiance, and a `perspective` sensor with `fov` and `to_world`. Test code only.

use super::add_box;
use glam::{Affine3A, Mat4, Vec3, Vec4};
use tracer::{Material, SceneInput};

/// One XML element: name, attributes, children (text content is ignored; Mitsuba puts data in attributes).
#[derive(Debug, Clone, Default)]
pub struct Element {
    pub name: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
}

impl Element {
    pub fn attr(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }
    /// Child with element name `name` and attribute name="`prop`".
    pub fn prop(&self, name: &str, prop: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name && c.attr("name") == Some(prop))
    }
}

/// Parses elements, skipping comments, processing instructions and text.
pub fn parse(xml: &str) -> Result<Element, String> {
    let mut stack = vec![Element { name: "#document".into(), ..Default::default() }];
    let mut rest = xml;
    while let Some(start) = rest.find('<') {
        rest = &rest[start..];
        if rest.starts_with("<!--") {
            let end = rest.find("-->").ok_or("unterminated comment")?;
            rest = &rest[end + 3..];
            continue;
        }
        if rest.starts_with("<?") || rest.starts_with("<!") {
            let end = rest.find('>').ok_or("unterminated declaration")?;
            rest = &rest[end + 1..];
            continue;
        }
        let end = rest.find('>').ok_or("unterminated tag")?;
        let tag = &rest[1..end];
        rest = &rest[end + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            let done = stack.pop().ok_or("unbalanced close tag")?;
            if done.name != name.trim() {
                return Err(format!("close tag {name} does not match {}", done.name));
            }
            stack.last_mut().ok_or("close tag at top level")?.children.push(done);
            continue;
        }
        let self_closing = tag.ends_with('/');
        let tag = tag.trim_end_matches('/');
        let (name, mut attrs_str) = tag.split_once(char::is_whitespace).unwrap_or((tag, ""));
        let mut el = Element { name: name.to_string(), ..Default::default() };
        loop {
            attrs_str = attrs_str.trim_start();
            if attrs_str.is_empty() {
                break;
            }
            let eq = attrs_str.find('=').ok_or_else(|| format!("attribute without value in <{name}>"))?;
            let key = attrs_str[..eq].trim().to_string();
            let after = attrs_str[eq + 1..].trim_start();
            let q = after.chars().next().ok_or("missing quote")?;
            let close = after[1..].find(q).ok_or("unterminated attribute")?;
            el.attrs.push((key, after[1..1 + close].to_string()));
            attrs_str = &after[close + 2..];
        }
        if self_closing {
            stack.last_mut().ok_or("no parent")?.children.push(el);
        } else {
            stack.push(el);
        }
    }
    if stack.len() != 1 {
        return Err(format!("{} unclosed elements", stack.len() - 1));
    }
    Ok(stack.pop().unwrap_or_default())
}

fn floats(s: &str) -> Result<Vec<f32>, String> {
    s.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f32>().map_err(|e| format!("bad number {t:?}: {e}")))
        .collect()
}

fn rgb(e: &Element) -> Result<Vec3, String> {
    let v = floats(e.attr("value").ok_or("rgb without value")?)?;
    match v[..] {
        [x] => Ok(Vec3::splat(x)),
        [r, g, b] => Ok(Vec3::new(r, g, b)),
        _ => Err(format!("rgb with {} components", v.len())),
    }
}

/// Row-major 4×4 `matrix value` of a `transform` element.
fn to_world(parent: &Element) -> Result<Mat4, String> {
    let Some(t) = parent.prop("transform", "to_world") else { return Ok(Mat4::IDENTITY) };
    let m = t.child("matrix").ok_or("to_world without matrix")?;
    let v = floats(m.attr("value").ok_or("matrix without value")?)?;
    if v.len() != 16 {
        return Err(format!("matrix with {} entries", v.len()));
    }
    let row = |i: usize| Vec4::new(v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]);
    Ok(Mat4::from_cols(row(0), row(1), row(2), row(3)).transpose())
}

/// The scene as tracer input: one material and one emitter slot per shape (emitter slot i emits
/// `emission[i]`), plus the camera converted to our convention (Mitsuba's camera looks down +z with +x to
/// the left of the image, ours down −z with +x to the right: cam_to_world = to_world · diag(−1, 1, −1)).
pub struct Loaded {
    pub input: SceneInput,
    pub materials: Vec<Material>,
    pub emission: Vec<Vec3>,
    pub fov_deg: f32,
    pub cam_to_world: Affine3A,
}

pub fn load(xml: &str) -> Result<Loaded, String> {
    let doc = parse(xml)?;
    let scene = doc.child("scene").ok_or("no <scene>")?;
    let mut bsdfs = std::collections::HashMap::new();
    for b in scene.children.iter().filter(|c| c.name == "bsdf") {
        let inner = if b.attr("type") == Some("twosided") { b.child("bsdf").ok_or("empty twosided")? } else { b };
        if inner.attr("type") != Some("diffuse") {
            return Err(format!("unsupported bsdf type {:?}", inner.attr("type")));
        }
        let refl = inner.prop("rgb", "reflectance").map(rgb).transpose()?.unwrap_or(Vec3::splat(0.5));
        bsdfs.insert(b.attr("id").unwrap_or_default().to_string(), refl);
    }
    let mut input = SceneInput::default();
    let (mut materials, mut emission) = (Vec::new(), Vec::new());
    for (slot, shape) in scene.children.iter().filter(|c| c.name == "shape").enumerate() {
        let slot = slot as u32;
        let m = to_world(shape)?;
        let id = shape.child("ref").and_then(|r| r.attr("id")).ok_or("shape without bsdf ref")?;
        let refl = *bsdfs.get(id).ok_or_else(|| format!("unknown bsdf {id}"))?;
        materials.push(Material { base_color: refl, roughness: 1.0, metallic: 0.0, specular: 0.0 });
        let e = match shape.child("emitter") {
            Some(em) => em.prop("rgb", "radiance").map(rgb).transpose()?.ok_or("emitter without radiance")?,
            None => Vec3::ZERO,
        };
        emission.push(e);
        let first_vertex = input.positions.len();
        let first_tri = input.triangles.len();
        match shape.attr("type") {
            Some("rectangle") => {
                let p = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(x, y)| Vec3::new(x, y, 0.0));
                super::add_quad(&mut input, p, slot, slot);
            }
            Some("cube") => add_box(&mut input, Vec3::splat(-1.0), Vec3::splat(1.0), false, slot, slot),
            other => return Err(format!("unsupported shape type {other:?}")),
        }
        for p in &mut input.positions[first_vertex..] {
            *p = m.transform_point3(*p);
        }
        // Mitsuba transforms normals by the inverse transpose, so a mirroring to_world keeps the front side
        // where the transformed normal points; the transformed winding would flip it.
        if m.determinant() < 0.0 {
            for t in &mut input.triangles[first_tri..] {
                t.swap(1, 2);
            }
        }
    }
    let sensor = scene.child("sensor").ok_or("no sensor")?;
    if sensor.attr("type") != Some("perspective") {
        return Err("only perspective sensors".into());
    }
    let fov_deg = floats(sensor.prop("float", "fov").and_then(|f| f.attr("value")).ok_or("sensor without fov")?)?[0];
    let cam = to_world(sensor)? * Mat4::from_scale(Vec3::new(-1.0, 1.0, -1.0));
    Ok(Loaded { input, materials, emission, fov_deg, cam_to_world: Affine3A::from_mat4(cam) })
}
