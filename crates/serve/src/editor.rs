//! Edit sessions: a material moved along trait directions, every step kept valid.

use crate::error::{Result, ServeError};
use crate::library::lock;
use brdf::MerlTable;
use reduce::Model;
use serde::Serialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use traits::{Check, Navigator, NavigatorOptions, Session, Space, TraitSet, TraitVector};

/// Edit sessions kept at once; the least recently used is closed first. A session keeps the
/// back-projected table (17.5 MB) and one back-projected direction per trait used.
pub const MAX_SESSIONS: usize = 12;

/// One trait set with its navigator and the corpus's scores.
pub struct TraitSpace {
    /// The traits.
    pub set: TraitSet,
    nav: &'static Navigator<'static>,
    /// Coordinates of every model material in this space.
    corpus: HashMap<String, Vec<f64>>,
}

impl TraitSpace {
    /// Scores of a point of this space, in the set's order.
    pub fn scores(&self, x: &[f64]) -> Vec<f64> {
        self.set
            .traits
            .iter()
            .map(|t| t.direction.score(x))
            .collect()
    }

    /// Scores of a model material, when it is one.
    pub fn corpus_scores(&self, name: &str) -> Option<Vec<f64>> {
        self.corpus.get(name).map(|x| self.scores(x))
    }
}

/// The model, the trait spaces and the open sessions.
///
/// An [`EditSession`] moves a material along trait directions with [`traits::Session::nudge`],
/// every step stopped at the border of the valid set (the check that stopped it is reported),
/// with undo/redo, interpolation toward a second material, and the current table for every
/// other view and for export.
///
/// The model and one [`traits::Navigator`] per trait set are built once when the server starts
/// and live as long as the process (they are leaked on purpose: sessions borrow them).
///
/// # Examples
///
/// ```
/// use serve::Editor;
/// use traits::{fit_binary, FitOptions, Method, Space, TraitSet, TraitVector};
/// // Eight analytic materials, four matte and four glossy, and a 7-component model of them.
/// let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
/// for i in 0..8 {
///     let spec = if i < 4 {
///         format!("lambert:kd={}", 0.1 + 0.1 * i as f64)
///     } else {
///         format!("ggx:alpha={},kd=0.2,ks=0.1", 0.5 - 0.1 * (i - 4) as f64)
///     };
///     let table = brdf::load(&spec).unwrap().tabulate();
///     corpus.push_values(format!("m{i}"), &table.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 7, None, None).unwrap();
/// // A "glossy" trait in the first five PCA coordinates.
/// let coords = model.pca.coords.columns(0, 5).into_owned();
/// let labels: Vec<bool> = (0..8).map(|i| i >= 4).collect();
/// let direction = fit_binary(&coords, &labels, Method::Svm, &FitOptions::default()).unwrap();
/// let set = TraitSet {
///     space: Space::Linear,
///     dim: 5,
///     method: Method::Svm,
///     traits: vec![TraitVector { name: "glossy".into(), direction, cross_validated: None, variant: None }],
/// };
/// let editor = Editor::new(model, vec![set]).unwrap();
///
/// // Open a session on a corpus material (its coordinates are known, nothing is projected).
/// let x = editor.coords_of(0, "m2", || unreachable!()).unwrap();
/// let opened = editor.open(0, "m2", &x).unwrap();
/// let session = editor.get(opened.id).unwrap();
/// let mut s = session.lock().unwrap();
/// let step = editor.nudge(&mut s, "glossy", 0.4).unwrap();
/// assert!(step.applied.abs() <= 0.4);
/// assert_eq!(step.stopped_by.is_some(), step.message.is_some());
/// // The score moves by what was applied, and undo brings it back.
/// assert!((step.state.scores[0] - opened.scores[0] - step.applied).abs() < 1e-9);
/// let undone = editor.undo(&mut s).unwrap();
/// assert!((undone.scores[0] - opened.scores[0]).abs() < 1e-9);
/// assert_eq!((undone.undo, undone.redo), (0, 1));
/// editor.redo(&mut s).unwrap();
/// // Every table the editor hands out is physically valid.
/// let (table, report) = editor.table(&mut s).unwrap();
/// assert!(report.is_valid());
/// assert!(table.values().iter().all(|v| *v >= 0.0));
/// let spec = editor.spec(&s, "model.bin", "traits.json");
/// assert!(spec.command.starts_with("gantry edit m2"));
/// drop(s);
/// editor.close(opened.id).unwrap();
/// assert!(editor.get(opened.id).is_err());
/// ```
pub struct Editor {
    /// The model.
    pub model: &'static Model,
    /// One entry per `--traits` file.
    pub spaces: Vec<TraitSpace>,
    sessions: Mutex<Vec<(u64, Arc<Mutex<EditSession>>)>>,
    next_id: std::sync::atomic::AtomicU64,
}

#[derive(Debug, Clone)]
struct Snapshot {
    coords: Vec<f64>,
    edits: Vec<(String, f64)>,
}

/// Endpoints of an interpolation in progress.
#[derive(Debug, Clone)]
struct Interpolation {
    other: String,
    from: Vec<f64>,
    to: Vec<f64>,
}

/// One material being edited.
pub struct EditSession {
    /// Session id.
    pub id: u64,
    /// The material the session started from.
    pub start: String,
    /// Index of the trait space.
    pub space: usize,
    session: Session<'static, 'static>,
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
    edits: Vec<(String, f64)>,
    interpolation: Option<Interpolation>,
    /// Bumped by every change of the current point.
    pub version: u64,
    table: Option<(u64, Arc<MerlTable>, traits::ValidityReport)>,
}

/// What a step did, for the page.
#[derive(Debug, Clone, Serialize)]
pub struct StepResult {
    /// Amount asked for (trait units, or interpolation parameter change).
    pub requested: f64,
    /// Amount applied.
    pub applied: f64,
    /// The check that stopped the step short, if any.
    pub stopped_by: Option<Check>,
    /// The same in words.
    pub message: Option<String>,
    /// The session after the step.
    pub state: SessionState,
}

/// The state of a session the page shows.
#[derive(Debug, Clone, Serialize)]
pub struct SessionState {
    /// Session id.
    pub id: u64,
    /// Name under which the current point is a material (`edit:<id>`).
    pub material: String,
    /// Start material.
    pub start: String,
    /// Space of the traits.
    pub space: Space,
    /// Trait names.
    pub traits: Vec<String>,
    /// Current score per trait.
    pub scores: Vec<f64>,
    /// Applied steps, in order (trait, amount).
    pub edits: Vec<(String, f64)>,
    /// Net amount added per trait.
    pub totals: Vec<(String, f64)>,
    /// Version of the current point.
    pub version: u64,
    /// Undo steps available.
    pub undo: usize,
    /// Redo steps available.
    pub redo: usize,
    /// Interpolation in progress: the other material.
    pub interpolating_with: Option<String>,
    /// The model coefficients of the current point (what the real-time view draws).
    pub coefficients: Vec<f64>,
}

/// A reproducible description of an edit: the start, the space and the net amount per trait
/// (`gantry edit` with these `--add`s gives the same material in the linear space, where the
/// valid set is convex so the straight move meets no border), and the coordinates.
#[derive(Debug, Clone, Serialize)]
pub struct EditSpec {
    /// Start material.
    pub start: String,
    /// Space.
    pub space: Space,
    /// Net amount per trait.
    pub add: Vec<(String, f64)>,
    /// The equivalent command line (model and trait files named as given to the server).
    pub command: String,
    /// Coordinates of the edited material in the space.
    pub coords: Vec<f64>,
    /// Trait scores of the edited material.
    pub scores: Vec<(String, f64)>,
}

impl Editor {
    /// Loads the model and builds one navigator per trait set (in the set's space, with the
    /// set's dimension as the linear space's).
    pub fn new(model: Model, sets: Vec<TraitSet>) -> Result<Editor> {
        let model: &'static Model = Box::leak(Box::new(model));
        let mut spaces = Vec::new();
        for set in sets {
            let options = NavigatorOptions {
                linear_dim: if set.space == Space::Linear {
                    set.dim
                } else {
                    NavigatorOptions::default()
                        .linear_dim
                        .min(model.components())
                },
                ..Default::default()
            };
            let nav: &'static Navigator<'static> =
                Box::leak(Box::new(Navigator::new(model, set.space, options)?));
            if nav.embedding.dim() != set.dim {
                return Err(ServeError::InvalidParameter(format!(
                    "trait set of dimension {} does not fit the model's {:?} space of dimension {}",
                    set.dim,
                    set.space,
                    nav.embedding.dim()
                )));
            }
            let x = nav.embedding.corpus()?;
            let corpus = model
                .names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), x.row(i).iter().copied().collect()))
                .collect();
            spaces.push(TraitSpace { set, nav, corpus });
        }
        Ok(Editor {
            model,
            spaces,
            sessions: Mutex::new(Vec::new()),
            next_id: 1.into(),
        })
    }

    fn space(&self, i: usize) -> Result<&TraitSpace> {
        self.spaces
            .get(i)
            .ok_or_else(|| ServeError::InvalidParameter(format!("trait space {i}")))
    }

    /// Coordinates of a material in space `i`: a model material's own, otherwise the
    /// projection of its table (`values` gives it on demand).
    pub fn coords_of(
        &self,
        i: usize,
        name: &str,
        values: impl FnOnce() -> Result<Vec<f64>>,
    ) -> Result<Vec<f64>> {
        let sp = self.space(i)?;
        if let Some(x) = sp.corpus.get(name) {
            return Ok(x.clone());
        }
        Ok(sp.nav.embedding.project_values(&values()?)?)
    }

    /// Starts a session at `coords` of space `i` (from material `start`).
    pub fn open(&self, i: usize, start: &str, coords: &[f64]) -> Result<SessionState> {
        let sp = self.space(i)?;
        let session = Session::new(sp.nav, coords)?;
        let id = self
            .next_id
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let s = EditSession {
            id,
            start: start.to_string(),
            space: i,
            session,
            undo: Vec::new(),
            redo: Vec::new(),
            edits: Vec::new(),
            interpolation: None,
            version: 0,
            table: None,
        };
        let state = self.state_of(&s);
        let mut all = lock(&self.sessions);
        all.push((id, Arc::new(Mutex::new(s))));
        while all.len() > MAX_SESSIONS {
            let (gone, _) = all.remove(0);
            tracing::info!(session = gone, "edit session closed to free memory");
        }
        Ok(state)
    }

    /// The session with this id (marked as most recently used).
    pub fn get(&self, id: u64) -> Result<Arc<Mutex<EditSession>>> {
        let mut all = lock(&self.sessions);
        let i = all
            .iter()
            .position(|(k, _)| *k == id)
            .ok_or(ServeError::UnknownSession(id))?;
        let e = all.remove(i);
        let s = e.1.clone();
        all.push(e);
        Ok(s)
    }

    /// Closes a session.
    pub fn close(&self, id: u64) -> Result<()> {
        let mut all = lock(&self.sessions);
        let n = all.len();
        all.retain(|(k, _)| *k != id);
        if all.len() == n {
            return Err(ServeError::UnknownSession(id));
        }
        Ok(())
    }

    /// The page's view of a session.
    pub fn state_of(&self, s: &EditSession) -> SessionState {
        let sp = &self.spaces[s.space];
        let x = &s.session.state().coords;
        let mut totals: Vec<(String, f64)> = Vec::new();
        for (t, a) in &s.edits {
            match totals.iter_mut().find(|(n, _)| n == t) {
                Some(e) => e.1 += a,
                None => totals.push((t.clone(), *a)),
            }
        }
        SessionState {
            id: s.id,
            material: format!("edit:{}", s.id),
            start: s.start.clone(),
            space: sp.set.space,
            traits: sp.set.traits.iter().map(|t| t.name.clone()).collect(),
            scores: sp.scores(x),
            edits: s.edits.clone(),
            totals,
            version: s.version,
            undo: s.undo.len(),
            redo: s.redo.len(),
            interpolating_with: s.interpolation.as_ref().map(|i| i.other.clone()),
            coefficients: s.session.state().pca.clone(),
        }
    }

    fn trait_of<'a>(&'a self, s: &EditSession, name: &str) -> Result<&'a TraitVector> {
        self.spaces[s.space]
            .set
            .traits
            .iter()
            .find(|t| t.name == name)
            .ok_or_else(|| ServeError::UnknownTrait(name.into()))
    }

    fn snapshot(s: &EditSession) -> Snapshot {
        Snapshot {
            coords: s.session.state().coords.clone(),
            edits: s.edits.clone(),
        }
    }

    fn result(
        &self,
        s: &EditSession,
        requested: f64,
        applied: f64,
        why: Option<Check>,
    ) -> StepResult {
        let message = why.map(|c| {
            format!(
                "stopped by {c}: applied {applied:.3} of {requested:.3}{}",
                match c {
                    Check::NonNegativity => " (a BRDF value would fall below zero)",
                    Check::EnergyConservation =>
                        " (the directional albedo would exceed 1: more light out than in)",
                    Check::ConvexHull => " (outside the convex hull of the corpus)",
                    Check::Reciprocity => " (f(ωi, ωo) ≠ f(ωo, ωi))",
                }
            )
        });
        StepResult {
            requested,
            applied,
            stopped_by: why,
            message,
            state: self.state_of(s),
        }
    }

    /// Adds `amount` units of `trait_name` (as far as the result stays valid).
    pub fn nudge(&self, s: &mut EditSession, trait_name: &str, amount: f64) -> Result<StepResult> {
        if !amount.is_finite() || amount.abs() > 1e3 {
            return Err(ServeError::InvalidParameter(format!("amount {amount}")));
        }
        let tv = self.trait_of(s, trait_name)?.clone();
        let before = Self::snapshot(s);
        let (applied, why) = s.session.nudge(&tv, amount)?;
        if applied != 0.0 {
            s.undo.push(before);
            s.redo.clear();
            s.edits.push((tv.name.clone(), applied));
            s.interpolation = None;
            s.version += 1;
        }
        Ok(self.result(s, amount, applied, why))
    }

    /// Moves the trait's score to `target` (one nudge by the difference).
    pub fn set_score(
        &self,
        s: &mut EditSession,
        trait_name: &str,
        target: f64,
    ) -> Result<StepResult> {
        let tv = self.trait_of(s, trait_name)?;
        let now = tv.direction.score(&s.session.state().coords);
        self.nudge(s, trait_name, target - now)
    }

    /// Moves to the point `(1 − t)·a + t·b` between the session's point when the
    /// interpolation began (`a`) and material `other` (`b`, coordinates `to`), as far as the
    /// straight move from the current point stays valid.
    pub fn interpolate(
        &self,
        s: &mut EditSession,
        other: &str,
        to: impl FnOnce() -> Result<Vec<f64>>,
        t: f64,
    ) -> Result<StepResult> {
        if !(0.0..=1.0).contains(&t) {
            return Err(ServeError::InvalidParameter(format!("t = {t} (0 to 1)")));
        }
        if s.interpolation.as_ref().is_none_or(|i| i.other != other) {
            s.interpolation = Some(Interpolation {
                other: other.to_string(),
                from: s.session.state().coords.clone(),
                to: to()?,
            });
        }
        let ip = s.interpolation.clone().expect("set above");
        let x = &s.session.state().coords;
        let delta: Vec<f64> = (0..x.len())
            .map(|k| (1.0 - t) * ip.from[k] + t * ip.to[k] - x[k])
            .collect();
        let nav = self.spaces[s.space].nav;
        let (state, frac, why) = nav.step(s.session.state(), &delta)?;
        if frac > 0.0 {
            let before = Self::snapshot(s);
            s.session = Session::new(nav, &state.coords)?;
            s.undo.push(before);
            s.redo.clear();
            s.edits.push((format!("interpolate:{other}"), frac));
            s.version += 1;
        }
        let mut r = self.result(s, 1.0, frac, why);
        r.state.interpolating_with = Some(ip.other);
        Ok(r)
    }

    fn restore(&self, s: &mut EditSession, to: Snapshot) -> Result<()> {
        let nav = self.spaces[s.space].nav;
        s.session = Session::resume(nav, &to.coords)?;
        s.edits = to.edits;
        s.interpolation = None;
        s.version += 1;
        Ok(())
    }

    /// Undoes the last step (no-op without one).
    pub fn undo(&self, s: &mut EditSession) -> Result<SessionState> {
        if let Some(prev) = s.undo.pop() {
            let now = Self::snapshot(s);
            self.restore(s, prev)?;
            s.redo.push(now);
        }
        Ok(self.state_of(s))
    }

    /// Redoes the last undone step (no-op without one).
    pub fn redo(&self, s: &mut EditSession) -> Result<SessionState> {
        if let Some(next) = s.redo.pop() {
            let now = Self::snapshot(s);
            self.restore(s, next)?;
            s.undo.push(now);
        }
        Ok(self.state_of(s))
    }

    /// The lit sphere of the current point from the kept back-projection (no full table).
    pub fn preview(&self, s: &EditSession, p: &traits::SpherePreview) -> Vec<[f32; 3]> {
        s.session.preview(p)
    }

    /// The current table (clamped at 0) and its validity report, cached per version.
    pub fn table(&self, s: &mut EditSession) -> Result<(Arc<MerlTable>, traits::ValidityReport)> {
        if let Some((v, t, r)) = &s.table {
            if *v == s.version {
                return Ok((t.clone(), r.clone()));
            }
        }
        let (t, r) = s.session.table()?;
        let t = Arc::new(t.with_name(format!("edit:{}", s.id)));
        s.table = Some((s.version, t.clone(), r.clone()));
        Ok((t, r))
    }

    /// The reproducible description of the current edit.
    pub fn spec(&self, s: &EditSession, model_file: &str, traits_file: &str) -> EditSpec {
        let st = self.state_of(s);
        let add: Vec<(String, f64)> = st
            .totals
            .iter()
            .filter(|(n, _)| !n.starts_with("interpolate:"))
            .cloned()
            .collect();
        let mut command = format!(
            "gantry edit {} --traits {traits_file} --model {model_file}",
            s.start
        );
        for (n, a) in &add {
            command.push_str(&format!(" --add {n}={a:.6}"));
        }
        command.push_str(" --out edited.binary");
        EditSpec {
            start: s.start.clone(),
            space: st.space,
            add,
            command,
            coords: s.session.state().coords.clone(),
            scores: st.traits.into_iter().zip(st.scores).collect(),
        }
    }
}
