//! The `export` stage: the outputs a user reads and reuses.
//!
//! - `output.path/materials.json` — the fitted per-object materials, schema `ipt-materials/1`: the object
//!   stage's, summarised from the per-triangle result when the `triangle` stage wrote one
//!   ([`per_triangle_summary`]);
//! - `output.path/export/trajectories.csv` — one row per recorded fit iteration: every numeric (or text)
//!   field of the fit's history entries, nested fields flattened to dotted column names
//!   (`params.3.base_color.0`);
//! - `output.path/export/report.html` — self-contained report ([`crate::report`]): photos beside re-renders
//!   with the fitted materials and error maps, loss curves, the per-object table.
//!
//! - `output.path/export/mesh.ply`, `textured.obj` + `textured.mtl` + `albedo.png` / `albedo.exr`,
//!   `scene.glb` ([`crate::export::write_all`]): the per-triangle (subdivided) result of the `triangle` stage
//!   when it wrote one, else the per-object result expanded per triangle ([`export_mesh`], also what
//!   `pipeline export RUN_DIR` runs). The glTF scene is turned Y-up when the cameras' up axes say the scan is
//!   Z-up (Matterport and our synthetic scans are).

use std::path::PathBuf;

use crate::artefacts::ingest::Ingested;
use crate::artefacts::object::{MATERIALS_FILE, read_history, read_result};
use crate::artefacts::triangle;
use crate::atomic_file::{write_atomic, write_json_atomic};
use crate::config::profile_name;
use crate::plan::StageId;
use crate::report::{ReportData, RgbImage, Series, ViewPanel};
use crate::stage_contract::{Reporter, StageContext, StageError};

/// CSV file name inside the stage directory.
pub const TRAJECTORIES_FILE: &str = "trajectories.csv";
/// Report file name inside the stage directory.
pub const REPORT_FILE: &str = "report.html";

/// One table: header and rows of cells (empty where a row lacks the column).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<serde_json::Value>>,
}

/// Flattens JSON values into `(dotted name, scalar)` pairs; arrays index with their position, except that an
/// array with one entry per object is indexed by object id and an RGB triple by `r`, `g`, `b`
/// (`base_color.3.r` = red base colour of the object with id 3).
fn flatten(prefix: &str, v: &serde_json::Value, ids: &[i64], out: &mut Vec<(String, serde_json::Value)>) {
    let join = |k: &str| if prefix.is_empty() { k.to_owned() } else { format!("{prefix}.{k}") };
    match v {
        serde_json::Value::Object(m) => m.iter().for_each(|(k, x)| flatten(&join(k), x, ids, out)),
        serde_json::Value::Array(a) => {
            let per_object = !ids.is_empty() && a.len() == ids.len() && a.iter().all(serde_json::Value::is_array);
            let rgb = a.len() == 3 && a.iter().all(serde_json::Value::is_number);
            for (i, x) in a.iter().enumerate() {
                let key = if per_object {
                    ids[i].to_string()
                } else if rgb {
                    ["r", "g", "b"][i].to_owned()
                } else {
                    i.to_string()
                };
                flatten(&join(&key), x, ids, out);
            }
        }
        scalar => out.push((if prefix.is_empty() { "value".to_owned() } else { prefix.to_owned() }, scalar.clone())),
    }
}

/// The history entries as a table. Columns: `iteration` first, then the other scalar fields, then nested
/// ones, each group in first-seen order. `ids` are the object ids in the fit's object order.
#[must_use]
pub fn history_table(history: &[serde_json::Value], ids: &[i64]) -> Table {
    let flat: Vec<Vec<(String, serde_json::Value)>> = history
        .iter()
        .map(|h| {
            let mut out = Vec::new();
            flatten("", h, ids, &mut out);
            out
        })
        .collect();
    let mut columns: Vec<String> = Vec::new();
    for (k, _) in flat.iter().flatten() {
        if !columns.contains(k) {
            columns.push(k.clone());
        }
    }
    let rank = |c: &String| {
        if c == "iteration" {
            0
        } else if c.contains('.') {
            2
        } else {
            1
        }
    };
    columns.sort_by_key(rank); // stable: first-seen order within each group
    let index: std::collections::HashMap<&str, usize> =
        columns.iter().enumerate().map(|(i, c)| (c.as_str(), i)).collect();
    let rows = flat
        .iter()
        .map(|row| {
            let mut cells = vec![serde_json::Value::Null; columns.len()];
            for (k, v) in row {
                cells[index[k.as_str()]] = v.clone();
            }
            cells
        })
        .collect();
    Table { columns, rows }
}

fn csv_cell(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) if s.contains([',', '"', '\n']) => format!("\"{}\"", s.replace('"', "\"\"")),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// RFC 4180 CSV text of a table.
#[must_use]
pub fn to_csv(t: &Table) -> String {
    let mut s = t.columns.iter().map(|c| csv_cell(&serde_json::Value::String(c.clone()))).collect::<Vec<_>>().join(",");
    s.push('\n');
    for row in &t.rows {
        s.push_str(&row.iter().map(csv_cell).collect::<Vec<_>>().join(","));
        s.push('\n');
    }
    s
}

/// Loss curves: every numeric column whose name contains `loss`, against the `iteration` column (or the row
/// number when there is none).
#[must_use]
pub fn loss_series(t: &Table) -> Vec<Series> {
    let it = t.columns.iter().position(|c| c == "iteration");
    t.columns
        .iter()
        .enumerate()
        .filter(|(_, c)| c.to_lowercase().contains("loss"))
        .map(|(j, c)| Series {
            name: c.clone(),
            points: t
                .rows
                .iter()
                .enumerate()
                .filter_map(|(i, row)| {
                    let x = it.and_then(|k| row[k].as_f64()).unwrap_or(i as f64);
                    row[j].as_f64().map(|y| (x, y))
                })
                .collect(),
        })
        .filter(|s| !s.points.is_empty())
        .collect()
}

/// Indices of at most `k` views spread evenly over `n`.
#[must_use]
pub fn spread(n: usize, k: usize) -> Vec<usize> {
    if k == 0 || n == 0 {
        return Vec::new();
    }
    if k >= n {
        return (0..n).collect();
    }
    (0..k).map(|i| i * n / k).collect()
}

/// True when the cameras' up axes (camera +y in world) point mostly along world ±z: the scan is Z-up.
#[must_use]
pub fn scan_is_z_up(views: &[ingest::View]) -> bool {
    let up = views.iter().fold(glam::DVec3::ZERO, |acc, v| acc + v.camera.cam_to_world.y_axis.truncate());
    up.z.abs() > up.y.abs()
}

/// What [`export_mesh`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshExport {
    /// The files written, relative to the run directory.
    pub files: Vec<PathBuf>,
    /// What the sub-triangle detail did, when it ran.
    pub detail: Option<optim::triangle::detail::DetailReport>,
}

/// Writes the mesh exports of a run directory into `run_dir/export/` (see the module docs).
pub fn export_mesh(
    run_dir: &std::path::Path,
    reporter: &dyn Reporter,
    detail: Option<&DetailRequest<'_>>,
) -> Result<MeshExport, StageError> {
    export_mesh_of(run_dir, triangle::read_result(run_dir)?.as_ref(), reporter, detail)
}

/// [`export_mesh`] with the triangle stage's result already read (`None`: the stage wrote none).
fn export_mesh_of(
    run_dir: &std::path::Path,
    triangle_result: Option<&optim::triangle::TriangleState>,
    reporter: &dyn Reporter,
    detail: Option<&DetailRequest<'_>>,
) -> Result<MeshExport, StageError> {
    use crate::export::{ExportInput, ExportOptions, expand_per_object, write_all};
    let scene_data = Ingested::read(run_dir)?;
    let ids: Vec<i64> = scene_data.objects.iter().map(|o| o.id).collect();
    let segment = |o: u32| i32::try_from(ids[o as usize]).unwrap_or(i32::MAX);
    let opts = ExportOptions { z_up: scan_is_z_up(&scene_data.views), ..ExportOptions::default() };
    let dir = run_dir.join("export");
    let mut detail_report = None;
    let report = match triangle_result {
        Some(st) => {
            if let Some(t) = st.face_object.iter().position(|&o| o as usize >= ids.len()) {
                return Err(StageError::Artefact {
                    path: run_dir.join("triangle").join(triangle::RESULT_FILE),
                    message: format!("triangle {t}: object {} of {}", st.face_object[t], ids.len()),
                });
            }
            // Mesh formats carry one radiance per triangle: an emitter split at the horizon gets the uniform
            // one of the same flux.
            let per_object = st.uniform_emission(ids.len());
            let emission: Vec<glam::Vec3> = st.face_object.iter().map(|&o| per_object[o as usize]).collect();
            let segment_id: Vec<i32> = st.face_object.iter().map(|&o| segment(o)).collect();
            let grids = match detail {
                Some(req) if req.settings.max_texels > 0 => {
                    let (grids, r) = estimate_detail(&ids, st, req, reporter)?;
                    detail_report = Some(r);
                    Some(grids)
                }
                _ => None,
            };
            let input = ExportInput {
                positions: &st.positions,
                triangles: &st.triangles,
                materials: &st.materials,
                emission: &emission,
                segment_id: &segment_id,
                detail: grids.as_deref(),
            };
            write_all(&dir, &input, &opts)?
        }
        None => {
            let path = run_dir.join("object").join(MATERIALS_FILE);
            let result = read_result(run_dir)?;
            let params = result.params_for(&ids, &path)?;
            let uniform = result.uniform_emission_for(&ids, &path)?;
            let per = expand_per_object(&scene_data.face_object, &ids, &params.materials, &uniform)?;
            let input = ExportInput {
                positions: &scene_data.positions,
                triangles: &scene_data.triangles,
                materials: &per.materials,
                emission: &per.emission,
                segment_id: &per.segment_id,
                detail: None,
            };
            write_all(&dir, &input, &opts)?
        }
    };
    reporter.note(
        StageId::Export,
        &format!(
            "{} triangles, {} segments, atlas {}x{} → {}",
            report.atlas.triangles,
            report.segments,
            report.atlas.width,
            report.atlas.height,
            dir.display()
        ),
    );
    let files = report
        .files
        .iter()
        .map(|f| f.strip_prefix(run_dir).map(std::path::Path::to_path_buf).unwrap_or_else(|_| f.clone()))
        .collect();
    Ok(MeshExport { files, detail: detail_report })
}

/// What the sub-triangle detail needs besides the run directory (the export stage has it; `pipeline export`
/// exports without detail).
#[derive(Debug)]
pub struct DetailRequest<'a> {
    /// The per-object result: which objects are `diffuse` (only those get detail).
    pub materials: &'a crate::materials::MaterialsFile,
    pub prepared: &'a crate::artefacts::preprocess::Prepared,
    pub tracer: &'a tracer::TracerSettings,
    pub settings: optim::triangle::detail::DetailSettings,
}

/// Per object of `ids`, whether its triangles may get sub-triangle detail: its per-object model is `diffuse`
/// and the photos constrain it ([`crate::materials::ObjectMaterial::is_constrained`], as the per-triangle stage
/// reads it). An
/// object the object stage left unconstrained (seen in fewer pixels than a fit needs) keeps its value, a prior
/// or a start value, in the per-triangle stage, and the few pixels that see it are no texture either.
fn detail_eligible(ids: &[i64], materials: &crate::materials::MaterialsFile) -> Vec<bool> {
    ids.iter()
        .map(|id| materials.objects.iter().any(|o| o.id == *id && o.model == "diffuse" && o.is_constrained()))
        .collect()
}

/// The per-triangle texel grids of the triangle result `st` (`optim::triangle::detail`), for the objects
/// [`detail_eligible`] admits, and what the estimate did.
fn estimate_detail(
    ids: &[i64],
    st: &optim::triangle::TriangleState,
    req: &DetailRequest<'_>,
    reporter: &dyn Reporter,
) -> Result<(Vec<Option<optim::triangle::detail::TexelGrid>>, optim::triangle::detail::DetailReport), StageError> {
    let eligible = detail_eligible(ids, req.materials);
    let scene = st.scene().map_err(StageError::Triangle)?;
    let cameras = req.prepared.tracer_cameras();
    let progress = reporter.progress(StageId::Export, "detail", 1);
    let (grids, report) = optim::triangle::detail::estimate(
        &scene,
        st,
        &cameras,
        &req.prepared.images,
        req.tracer,
        &eligible,
        &req.settings,
        progress.as_ref(),
    )
    .map_err(StageError::Triangle)?;
    drop(progress);
    reporter.note(
        StageId::Export,
        &format!(
            "detail: {} texels on {} triangles (density {:.3} per best-view pixel) from {} pixels",
            report.texels, report.triangles, report.density, report.pixels
        ),
    );
    Ok((grids, report))
}

/// report.html's per-triangle section: triangle counts per object before/after the `triangle` stage,
/// what the sub-triangle detail did and `export/albedo.png`; `None` when the stage wrote no result.
fn triangle_section(
    run_dir: &std::path::Path,
    triangle_result: Option<&optim::triangle::TriangleState>,
    scene_data: &Ingested,
    detail: Option<optim::triangle::detail::DetailReport>,
) -> Option<crate::report::TriangleSection> {
    let st = triangle_result?;
    let k = scene_data.objects.len();
    let mut before = vec![0usize; k];
    for &o in &scene_data.face_object {
        if let Some(c) = before.get_mut(o as usize) {
            *c += 1;
        }
    }
    let after = st.triangles_per_object(k);
    let counts = scene_data
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| (o.id, o.label.clone().unwrap_or_default(), before[i], after[i]))
        .collect();
    let atlas_png = std::fs::read(run_dir.join("export").join("albedo.png")).ok();
    let over_budget = st.log.iter().map(|r| r.over_budget).sum();
    Some(crate::report::TriangleSection { counts, over_budget, detail, atlas_png })
}

/// The run's per-object result when the `triangle` stage wrote one: each object's base colour, roughness,
/// metallic and specular are the area-weighted means of its triangles' ([`optim::triangle::TriangleState::object_means`]),
/// its emission (and horizon halves) the per-triangle stage's, its triangle count the final mesh's; its `why` and
/// `constrained` stay the object stage's decisions, and so does its model unless the per-triangle stage's lobe
/// family look changed whether it has a lobe ([`lobe_model`]: then the model says what the object now is, and
/// `why` says where that came from). So `materials.json` agrees with the exported mesh,
/// and its base colours rest on every photo pixel the per-triangle stage fitted: on the 1280×1024 corpus house
/// the object-stage base colours are 0.071 off the truth (mean L1 over 179 objects), these 0.058
/// (docs/scale/README.md, "Per-object results from the per-triangle stage"). An object whose id the scan does
/// not list, or that has no triangle of positive area, keeps the object stage's values.
fn per_triangle_summary(
    object: crate::materials::MaterialsFile,
    st: &optim::triangle::TriangleState,
    ids: &[i64],
) -> crate::materials::MaterialsFile {
    let means = st.object_means(ids.len());
    let uniform = st.uniform_emission(ids.len());
    let counts = st.triangles_per_object(ids.len());
    let objects = object
        .objects
        .into_iter()
        .map(|mut o| {
            let Some(k) = ids.iter().position(|&id| id == o.id) else { return o };
            if let Some(m) = means[k] {
                o.base_color = m.base_color.to_array();
                o.roughness = m.roughness;
                o.metallic = m.metallic;
                o.specular = m.specular;
                if let Some(model) = lobe_model(&o) {
                    let note = format!(
                        "the per-triangle stage's lobe family look made it {model} (metallic {:.2}, specular {:.2}, \
                         roughness {:.2}; the triangle stage's round log has the test)",
                        o.metallic, o.specular, o.roughness
                    );
                    o.why = Some(match o.why.take() {
                        Some(why) if !why.is_empty() => format!("{why}; {note}"),
                        _ => note,
                    });
                    o.model = model.to_owned();
                }
            }
            o.triangles = counts[k];
            o.emission = uniform[k].to_array();
            o.horizon = crate::materials::HorizonEmission::of_slot(&st.horizon, &st.emission, k);
            o
        })
        .collect();
    crate::materials::MaterialsFile { objects, ..object }
}

/// The model of a constrained object without emission whose parameters `o` no longer match its object-stage
/// model: `specular` where its per-triangle means have a lobe (not [`tracer::Material::is_lambert`]) and the model
/// says `diffuse`, `diffuse` where they have none and it says `specular`; `None` where they agree, and for emitters
/// and unconstrained objects (the per-triangle stage keeps their per-object materials). The per-triangle stage's
/// lobe family look switches an object's family after the object stage has named it: on the 160×128 corpus house
/// it made two diffuse objects metals, which `materials.json` still called `diffuse`.
fn lobe_model(o: &crate::materials::ObjectMaterial) -> Option<&'static str> {
    if !o.is_constrained() {
        return None;
    }
    match (o.model.as_str(), !o.material().is_lambert()) {
        ("diffuse", true) => Some("specular"),
        ("specular", false) => Some("diffuse"),
        _ => None,
    }
}

/// Runs the stage.
pub fn run(ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
    let plan = ctx.plan;
    let scene_data = Ingested::read(&plan.output)?;
    let ids: Vec<i64> = scene_data.objects.iter().map(|o| o.id).collect();
    // Read once: the summary, the mesh export and the report's per-triangle section all use it.
    let triangle_result = triangle::read_result(&plan.output)?;
    let object = read_result(&plan.output)?;
    let materials = match &triangle_result {
        Some(st) => per_triangle_summary(object, st, &ids),
        None => object,
    };
    let history = read_history(&plan.output)?;
    write_json_atomic(&plan.output.join("materials.json"), &materials)?;

    let prepared = crate::artefacts::object::read_prepared(&plan.output)?;
    let table = history_table(&history.history, &ids);
    write_atomic(&ctx.dir.join(TRAJECTORIES_FILE), to_csv(&table).as_bytes())?;

    let params = materials.params_for(&ids, &plan.output.join("object").join(MATERIALS_FILE))?;
    let scene = tracer::Scene::new(scene_data.scene_input())?;
    let cameras = prepared.tracer_cameras();
    let settings = plan.tracer.settings();
    let chosen = spread(prepared.names.len(), plan.export.report_views as usize);
    let bar = ctx.progress("report re-renders", chosen.len() as u64);
    let mut views = Vec::new();
    for &v in &chosen {
        let img = &prepared.images[v];
        let render =
            tracer::render_image(&scene, &params, &cameras[v], plan.export.report_spp, &settings, plan.export.seed, 0)?;
        views.push(ViewPanel {
            name: prepared.names[v].clone(),
            photo: RgbImage { width: img.width, height: img.height, rgb: img.rgb.clone() },
            render: RgbImage {
                width: img.width,
                height: img.height,
                rgb: render.iter().flat_map(|c| c.to_array()).collect(),
            },
            mask: img.mask.clone(),
        });
        bar.inc(1);
    }
    drop(bar);
    let calibration = crate::artefacts::preprocess::CalibrationFile::read(&plan.output)?;
    let mut notes = vec![
        format!("config: {}", plan.config_path.display()),
        format!(
            "{} triangles, {} objects, {} prepared views; re-renders at {} paths per pixel, max depth {}",
            scene_data.triangles.len(),
            scene_data.objects.len(),
            prepared.names.len(),
            plan.export.report_spp,
            plan.tracer.max_depth
        ),
    ];
    if triangle_result.is_some() {
        notes.push(
            "objects and re-renders: each object's materials are the area-weighted means of its triangles' in the \
             per-triangle result, its emission that stage's (the object stage's own: object/materials.json)"
                .to_owned(),
        );
    }
    notes.extend(preparation_notes(plan, &scene_data, &prepared, calibration.is_some()));
    let data = ReportData {
        title: format!("Inverse path tracing: {}", plan.scan.path.display()),
        emission_profile: profile_name(materials.emission_profile).to_owned(),
        views,
        loss: loss_series(&table),
        objects: materials.objects.clone(),
        why: history.why.clone(),
        triangle: None,
        calibration,
        photometric: crate::artefacts::object::read_photometric(&plan.output)?,
        // history.json files written before the counts existed hold 0 paths: nothing to show then.
        samples: (history.traced_paths > 0).then_some(crate::report::SampleCounts {
            traced_paths: history.traced_paths,
            discarded: history.discarded_samples,
        }),
        notes,
    };
    // The mesh export first: report.html shows its albedo atlas in the per-triangle section.
    let request = DetailRequest {
        materials: &materials,
        prepared: &prepared,
        tracer: &settings,
        settings: optim::triangle::detail::DetailSettings {
            max_texels: plan.export.detail_texels,
            density: plan.export.detail_density,
            spp: plan.export.detail_spp,
            seed: plan.export.seed,
        },
    };
    let mesh = export_mesh_of(&plan.output, triangle_result.as_ref(), ctx.reporter, Some(&request))?;
    let mut data = data;
    data.triangle = triangle_section(&plan.output, triangle_result.as_ref(), &scene_data, mesh.detail);
    write_atomic(&ctx.dir.join(REPORT_FILE), crate::report::html(&data).as_bytes())?;
    let mut files = vec![
        PathBuf::from("materials.json"),
        PathBuf::from("export").join(TRAJECTORIES_FILE),
        PathBuf::from("export").join(REPORT_FILE),
    ];
    files.extend(mesh.files);
    ctx.note(&format!("wrote {}", plan.output.join("materials.json").display()));
    Ok(files)
}

/// What the preprocess stage decided about the photos, read back from its artefacts: the size the photos were
/// prepared at (and the downscale factor, which the pixel budget may have raised), and a photometric
/// calibration the config asked for but the photos' overlap did not support (the stage then prepares every
/// photo with one exposure; its reason is in the run log).
fn preparation_notes(
    plan: &crate::plan::Plan,
    scene: &Ingested,
    prepared: &crate::artefacts::preprocess::Prepared,
    calibrated: bool,
) -> Vec<String> {
    let mut notes = Vec::new();
    let source = prepared.names.first().and_then(|n| scene.views.iter().find(|v| &v.name == n));
    if let (Some(src), Some(cam)) = (source, prepared.cameras.first()) {
        let factor = src.camera.width / cam.width.max(1);
        let budget = if factor > plan.images.downscale {
            format!(", raised from images.downscale = {} by images.max_pixels", plan.images.downscale)
        } else {
            String::new()
        };
        notes.push(format!(
            "photos prepared at {}×{} from {}×{} (downscale {factor}{budget})",
            cam.width, cam.height, src.camera.width, src.camera.height
        ));
    }
    if plan.images.calibrates() && !calibrated {
        notes.push(
            "photometric calibration asked for but not applied: the photos' overlap did not support it \
             (reason in run.log); every photo has one exposure and white balance"
                .to_owned(),
        );
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn history_flattens_by_object_id_and_channel_with_iteration_first() {
        let h = vec![
            json!({"loss": 2.0, "iteration": 0, "base_color": [[0.5, 0.25, 0.0], [1.0, 1.0, 1.0]], "w": [7, 8]}),
            json!({"iteration": 10, "loss": 1.0, "note": "a,b"}),
        ];
        let t = history_table(&h, &[3, 9]);
        assert_eq!(
            t.columns,
            [
                "iteration",
                "loss",
                "note",
                "base_color.3.r",
                "base_color.3.g",
                "base_color.3.b",
                "base_color.9.r",
                "base_color.9.g",
                "base_color.9.b",
                "w.0",
                "w.1"
            ]
        );
        let csv = to_csv(&t);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[1], "0,2.0,,0.5,0.25,0.0,1.0,1.0,1.0,7,8");
        assert_eq!(lines[2], "10,1.0,\"a,b\",,,,,,,,");
        let s = loss_series(&t);
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].points, [(0.0, 2.0), (10.0, 1.0)]);
    }

    #[test]
    fn the_summary_of_a_triangle_result_averages_each_object_by_area_and_keeps_its_decisions() {
        use crate::materials::{MATERIALS_FORMAT, MaterialsFile};
        use glam::Vec3;
        let m = |x: f32| tracer::Material {
            base_color: Vec3::new(x, 0.5, 1.0 - x),
            roughness: x,
            metallic: 0.0,
            specular: 0.5,
        };
        // Object index 0 (id 7): a unit right triangle (area ½) at 0.2 and one of area 1.5 at 0.6, so its mean
        // is (0.5·0.2 + 1.5·0.6)/2 = 0.5. Object index 1 (id 4): one triangle, an emitter split at the horizon.
        let st = optim::triangle::TriangleState {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0)],
            normals: None,
            triangles: vec![[0, 1, 2], [0, 3, 2], [0, 1, 4]],
            face_object: vec![0, 0, 1],
            materials: vec![m(0.2), m(0.6), m(0.9)],
            emission: vec![Vec3::ZERO, Vec3::new(3.0, 2.0, 1.0), Vec3::new(0.5, 0.4, 0.3)],
            horizon: tracer::params::Horizon { up: Vec3::Z, ground: vec![None, Some(2)], zenith: Vec::new() },
            rounds_done: 1,
            log: Vec::new(),
        };
        let object = |id: i64, model: &str| crate::materials::test_object(id, model, Some(true));
        // The file lists the objects in another order than the scan, and one the scan does not have.
        let file = MaterialsFile {
            format: MATERIALS_FORMAT.into(),
            emission_profile: tracer::EmissionProfile::Uniform,
            objects: vec![object(4, "diffuse+emission"), object(99, "diffuse"), object(7, "specular")],
        };
        let out = per_triangle_summary(file.clone(), &st, &[7, 4]);
        let o7 = &out.objects[2];
        assert_eq!(o7.id, 7);
        for (got, want) in o7.base_color.iter().zip([0.5, 0.5, 0.5]) {
            assert!((got - want).abs() < 1e-6, "{:?}", o7.base_color);
        }
        assert!((o7.roughness - 0.5).abs() < 1e-6 && (o7.specular - 0.5).abs() < 1e-6);
        assert_eq!((o7.triangles, o7.emission, o7.horizon), (2, [0.0; 3], None));
        assert_eq!((o7.model.as_str(), o7.why.as_deref(), o7.constrained), ("specular", Some("why 7"), Some(true)));
        let o4 = &out.objects[0];
        assert_eq!(o4.base_color, [0.9, 0.5, 1.0 - 0.9]);
        assert_eq!(o4.emission, st.uniform_emission(2)[1].to_array());
        let h = o4.horizon.expect("split emitter keeps its halves");
        assert_eq!((h.up, h.sky, h.ground), ([0.0, 0.0, 1.0], [3.0, 2.0, 1.0], [0.5, 0.4, 0.3]));
        assert_eq!(out.objects[1], file.objects[1], "an object the scan does not list is kept as it was");
    }

    #[test]
    fn the_summary_names_an_object_by_the_lobe_family_its_triangles_ended_in() {
        use crate::materials::{MATERIALS_FORMAT, MaterialsFile};
        use glam::Vec3;
        let m = |metallic: f32, specular: f32| tracer::Material {
            base_color: Vec3::splat(0.4),
            roughness: 0.45,
            metallic,
            specular,
        };
        // Four objects of one triangle each: ids 1 and 2 were diffuse in the object stage, 3 and 4 specular; the
        // per-triangle stage's look made 1 a metal and 3 a Lambert surface, and left 2 and 4 as they were.
        let st = optim::triangle::TriangleState {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: None,
            triangles: vec![[0, 1, 2]; 4],
            face_object: vec![0, 1, 2, 3],
            materials: vec![m(1.0, 0.5), m(0.0, 0.0), m(0.0, 0.0), m(0.0, 0.5)],
            emission: vec![Vec3::ZERO; 4],
            horizon: tracer::params::Horizon { up: Vec3::Z, ground: vec![None; 4], zenith: Vec::new() },
            rounds_done: 1,
            log: Vec::new(),
        };
        let file = MaterialsFile {
            format: MATERIALS_FORMAT.into(),
            emission_profile: tracer::EmissionProfile::Uniform,
            objects: vec![
                crate::materials::test_object(1, "diffuse", Some(true)),
                crate::materials::test_object(2, "diffuse", Some(true)),
                crate::materials::test_object(3, "specular", Some(true)),
                crate::materials::test_object(4, "specular", Some(true)),
            ],
        };
        let out = per_triangle_summary(file, &st, &[1, 2, 3, 4]);
        let models: Vec<&str> = out.objects.iter().map(|o| o.model.as_str()).collect();
        assert_eq!(models, ["specular", "diffuse", "diffuse", "specular"]);
        let why1 = out.objects[0].why.as_deref().unwrap_or_default();
        assert!(
            why1.starts_with("why 1; the per-triangle stage's lobe family look made it specular (metallic 1.00"),
            "{why1}"
        );
        assert_eq!(out.objects[1].why.as_deref(), Some("why 2"), "an object whose family stayed keeps its why");
        assert!(out.objects[2].why.as_deref().unwrap_or_default().contains("made it diffuse"));
        // An unconstrained object or an emitter is named as the object stage named it, whatever its values.
        let mut o = crate::materials::test_object(5, "diffuse", Some(false));
        o.metallic = 1.0;
        assert_eq!(lobe_model(&o), None);
        o.constrained = Some(true);
        o.model = "diffuse+emission".into();
        assert_eq!(lobe_model(&o), None);
    }

    #[test]
    fn detail_goes_only_to_diffuse_objects_the_photos_constrain() {
        use crate::materials::{MATERIALS_FORMAT, MaterialsFile};
        let file = MaterialsFile {
            format: MATERIALS_FORMAT.into(),
            emission_profile: tracer::EmissionProfile::Uniform,
            objects: vec![
                crate::materials::test_object(1, "diffuse", Some(true)),
                crate::materials::test_object(2, "diffuse", Some(false)),
                crate::materials::test_object(3, "diffuse", None),
                crate::materials::test_object(4, "specular", Some(true)),
            ],
        };
        // Id 5 is not in the file: nothing says it is diffuse. A file written by hand (no `constrained`)
        // counts as constrained, as in the per-triangle stage.
        assert_eq!(detail_eligible(&[1, 2, 3, 4, 5], &file), [true, false, true, false, false]);
    }

    #[test]
    fn spread_picks_evenly_and_caps() {
        assert_eq!(spread(10, 3), [0, 3, 6]);
        assert_eq!(spread(2, 6), [0, 1]);
        assert!(spread(5, 0).is_empty());
    }
}
