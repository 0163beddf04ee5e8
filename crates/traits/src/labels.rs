//! Label sets: binary trait labels and graded ratings.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::error::{Result, TraitsError};

/// Fewest labels of each class a trait needs ([`LabelSet::check`]).
pub const MIN_PER_CLASS: usize = 3;

/// One material's label for one trait (thesis §5.1: `y = 1`, `y = −1` or unspecified).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Label {
    /// The trait is present (`y = 1`).
    Present,
    /// The trait is absent (`y = −1`).
    Absent,
    /// Hard to determine or not applicable.
    Unspecified,
}

/// A table of per-material values for a list of named traits: binary trait labels (present /
/// absent / unspecified, [`LabelSet`]) or graded ratings ([`RatingSet`]).
///
/// # File format (CSV)
///
/// Lines starting with `#` and blank lines are ignored. The first remaining line is the header
/// `material,<trait>,<trait>,...`; every following line names one material and gives one cell
/// per trait. For **binary labels** a cell is `1` (the trait is present), `-1` (absent) or empty
/// (unspecified, thesis §5.1). For **ratings** a cell is a number in `[0, 1]` or empty.
/// Material names are those of the model's corpus (`blue-acrylic`, …). Duplicate materials or
/// traits, unknown cells and ragged rows are parse errors with the line number.
#[derive(Debug, Clone, PartialEq)]
pub struct Table<T> {
    /// Trait names, in column order.
    pub traits: Vec<String>,
    /// Material names, in row order.
    pub materials: Vec<String>,
    /// `values[material][trait]`.
    pub values: Vec<Vec<T>>,
}

/// Binary labels (thesis §5.1).
///
/// # Examples
///
/// ```
/// use std::path::Path;
/// use traits::{Label, LabelSet, MIN_PER_CLASS};
/// let csv = "# a comment\nmaterial,glossy,red\nm0,1,-1\nm1,-1,\nm2,1,1\n";
/// let labels = LabelSet::parse(csv, Path::new("labels.csv")).unwrap();
/// assert_eq!(labels.traits, ["glossy", "red"]);
/// let red = labels.trait_index("red").unwrap();
/// assert_eq!(labels.column(red)[1], ("m1", Label::Unspecified));
/// assert_eq!(labels.counts(labels.trait_index("glossy").unwrap()), (2, 1));
/// // Three materials are too few to fit a trait ([`MIN_PER_CLASS`] of each class).
/// assert!(MIN_PER_CLASS > 1);
/// let names: Vec<String> = ["m0", "m1", "m2"].map(String::from).to_vec();
/// assert!(labels.check(&names).is_err());
/// // Cells other than 1, -1 or empty are refused.
/// assert!(LabelSet::parse("material,glossy\nm0,yes\n", Path::new("bad.csv")).is_err());
/// ```
pub type LabelSet = Table<Label>;
/// Graded ratings in `[0, 1]` (`None` = not rated).
pub type RatingSet = Table<Option<f64>>;

impl<T: Copy> Table<T> {
    /// Column of a trait.
    pub fn trait_index(&self, name: &str) -> Result<usize> {
        self.traits
            .iter()
            .position(|t| t == name)
            .ok_or_else(|| TraitsError::UnknownTrait(name.into()))
    }

    /// `(material, value)` pairs of one trait.
    pub fn column(&self, t: usize) -> Vec<(&str, T)> {
        self.materials
            .iter()
            .zip(&self.values)
            .map(|(m, v)| (m.as_str(), v[t]))
            .collect()
    }

    /// The rows of the materials in `corpus` only, and of the traits only those that `usable`
    /// accepts on these rows (a trait's column index in the restricted table).
    pub fn restricted(&self, corpus: &[String], usable: impl Fn(&Self, usize) -> bool) -> Self {
        let known: HashSet<&str> = corpus.iter().map(|s| s.as_str()).collect();
        let rows: Vec<usize> = (0..self.materials.len())
            .filter(|&i| known.contains(self.materials[i].as_str()))
            .collect();
        let on_corpus = Table {
            traits: self.traits.clone(),
            materials: rows.iter().map(|&i| self.materials[i].clone()).collect(),
            values: rows.iter().map(|&i| self.values[i].clone()).collect(),
        };
        let keep: Vec<usize> = (0..self.traits.len())
            .filter(|&t| usable(&on_corpus, t))
            .collect();
        Table {
            traits: keep.iter().map(|&t| self.traits[t].clone()).collect(),
            materials: on_corpus.materials,
            values: on_corpus
                .values
                .iter()
                .map(|row| keep.iter().map(|&t| row[t]).collect())
                .collect(),
        }
    }

    /// Checks that every material is one of `corpus` (e.g. the model's names).
    pub fn check_materials(&self, corpus: &[String]) -> Result<()> {
        let known: HashSet<&str> = corpus.iter().map(|s| s.as_str()).collect();
        match self.materials.iter().find(|m| !known.contains(m.as_str())) {
            Some(m) => Err(TraitsError::UnknownMaterial(m.clone())),
            None => Ok(()),
        }
    }
}

impl LabelSet {
    /// Parses binary labels from CSV text (`path` is used in messages only).
    pub fn parse(text: &str, path: &Path) -> Result<LabelSet> {
        parse_table(text, path, |cell| match cell {
            "1" | "+1" => Ok(Label::Present),
            "-1" => Ok(Label::Absent),
            "" => Ok(Label::Unspecified),
            other => Err(format!("label {other:?} is not 1, -1 or empty")),
        })
    }

    /// Reads a binary label file.
    pub fn load(path: impl AsRef<Path>) -> Result<LabelSet> {
        let p = path.as_ref();
        let text = std::fs::read_to_string(p).map_err(|e| TraitsError::io(p, e))?;
        LabelSet::parse(&text, p)
    }

    /// Number of `(present, absent)` labels of a trait.
    pub fn counts(&self, t: usize) -> (usize, usize) {
        let col = self.column(t);
        (
            col.iter().filter(|(_, l)| *l == Label::Present).count(),
            col.iter().filter(|(_, l)| *l == Label::Absent).count(),
        )
    }

    /// Checks the materials against `corpus` and that every trait has at least
    /// [`MIN_PER_CLASS`] labels of each class.
    pub fn check(&self, corpus: &[String]) -> Result<()> {
        self.check_materials(corpus)?;
        for (t, name) in self.traits.iter().enumerate() {
            let (present, absent) = self.counts(t);
            if present < MIN_PER_CLASS || absent < MIN_PER_CLASS {
                return Err(TraitsError::TooFewLabels {
                    name: name.clone(),
                    present,
                    absent,
                    min: MIN_PER_CLASS,
                });
            }
        }
        Ok(())
    }
}

impl RatingSet {
    /// Parses ratings in `[0, 1]` from CSV text.
    pub fn parse(text: &str, path: &Path) -> Result<RatingSet> {
        parse_table(text, path, |cell| {
            if cell.is_empty() {
                return Ok(None);
            }
            let v: f64 = cell
                .parse()
                .map_err(|_| format!("rating {cell:?} is not a number"))?;
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("rating {v} is outside [0, 1]"));
            }
            Ok(Some(v))
        })
    }

    /// Reads a rating file.
    pub fn load(path: impl AsRef<Path>) -> Result<RatingSet> {
        let p = path.as_ref();
        let text = std::fs::read_to_string(p).map_err(|e| TraitsError::io(p, e))?;
        RatingSet::parse(&text, p)
    }

    /// Checks the materials against `corpus` and that every trait has at least
    /// `min` ratings.
    pub fn check(&self, corpus: &[String], min: usize) -> Result<()> {
        self.check_materials(corpus)?;
        for (t, name) in self.traits.iter().enumerate() {
            let n = self.column(t).iter().filter(|(_, v)| v.is_some()).count();
            if n < min {
                return Err(TraitsError::TooFewLabels {
                    name: name.clone(),
                    present: n,
                    absent: 0,
                    min,
                });
            }
        }
        Ok(())
    }
}

/// The human ratings of the shared data (`ratings/serrano2016.csv` under `brdf::data_dir()`).
pub fn serrano_ratings_path() -> PathBuf {
    brdf::data_dir().join("ratings").join("serrano2016.csv")
}

fn parse_table<T>(
    text: &str,
    path: &Path,
    cell: impl Fn(&str) -> std::result::Result<T, String>,
) -> Result<Table<T>> {
    let err = |line: usize, message: String| TraitsError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hline, header) = lines
        .next()
        .ok_or_else(|| err(1, "no header line".into()))?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    if cols.len() < 2 || cols[0] != "material" {
        return Err(err(
            hline,
            "header must be `material,<trait>,...` with at least one trait".into(),
        ));
    }
    let traits: Vec<String> = cols[1..].iter().map(|s| s.to_string()).collect();
    let mut seen = HashSet::new();
    for t in &traits {
        if t.is_empty() || !seen.insert(t.as_str()) {
            return Err(err(hline, format!("empty or duplicate trait name {t:?}")));
        }
    }
    let mut materials = Vec::new();
    let mut values = Vec::new();
    let mut seen_m = HashSet::new();
    for (ln, line) in lines {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != cols.len() {
            return Err(err(
                ln,
                format!("{} cells, the header has {}", cells.len(), cols.len()),
            ));
        }
        let name = cells[0];
        if name.is_empty() || !seen_m.insert(name.to_string()) {
            return Err(err(ln, format!("empty or duplicate material {name:?}")));
        }
        let row = cells[1..]
            .iter()
            .map(|c| cell(c))
            .collect::<std::result::Result<Vec<T>, String>>()
            .map_err(|m| err(ln, m))?;
        materials.push(name.to_string());
        values.push(row);
    }
    if materials.is_empty() {
        return Err(err(hline, "no material rows".into()));
    }
    Ok(Table {
        traits,
        materials,
        values,
    })
}

/// The thesis's 16 traits labelled for the 96 shared MERL materials (shipped with the crate;
/// see docs/traits.md for how the labels were made).
pub fn thesis_labels() -> LabelSet {
    const TEXT: &str = include_str!("../data/thesis_traits.csv");
    LabelSet::parse(TEXT, Path::new("data/thesis_traits.csv"))
        .expect("the shipped label file parses (checked by a test)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_errors_name_the_line() {
        let p = Path::new("x.csv");
        let bad = [
            ("", "no header"),
            ("name,a\nm,1\n", "header"),
            ("material,a,a\nm,1,1\n", "duplicate trait"),
            ("material,a\nm,1\nm,-1\n", "duplicate material"),
            ("material,a\nm,2\n", "is not 1"),
            ("material,a,b\nm,1\n", "cells"),
        ];
        for (text, want) in bad {
            match LabelSet::parse(text, p) {
                Err(TraitsError::Parse { message, .. }) => {
                    assert!(message.contains(want), "{text:?}: {message}")
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
        let e = LabelSet::parse("# c\nmaterial,a\n\nm,1\nn,2\n", p).unwrap_err();
        assert!(matches!(e, TraitsError::Parse { line: 5, .. }), "{e}");
        assert!(RatingSet::parse("material,a\nm,1.5\n", p).is_err());
        let r = RatingSet::parse("material,a,b\nm,0.25,\n", p).unwrap();
        assert_eq!(r.values[0], vec![Some(0.25), None]);
    }

    #[test]
    fn check_rejects_unknown_materials_and_thin_traits() {
        let p = Path::new("x.csv");
        let l = LabelSet::parse(
            "material,a,b\nm1,1,1\nm2,1,-1\nm3,1,\nm4,-1,-1\nm5,-1,-1\nm6,-1,-1\n",
            p,
        )
        .unwrap();
        let corpus: Vec<String> = (1..=6).map(|i| format!("m{i}")).collect();
        match l.check(&corpus) {
            Err(TraitsError::TooFewLabels {
                name,
                present: 1,
                absent: 4,
                ..
            }) => assert_eq!(name, "b"),
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            l.check(&corpus[1..]),
            Err(TraitsError::UnknownMaterial(m)) if m == "m1"
        ));
        assert_eq!(l.counts(0), (3, 3));
        assert!(matches!(
            l.trait_index("c"),
            Err(TraitsError::UnknownTrait(_))
        ));
    }

    #[test]
    fn shipped_thesis_labels_cover_the_corpus_and_every_trait() {
        let l = thesis_labels();
        assert_eq!(l.traits.len(), 16);
        assert_eq!(l.materials.len(), 96);
        // Every trait is decidable: enough labels of each class.
        l.check(&l.materials.clone()).unwrap();
        // The materials are the shared MERL set (when the data is here; the names alone).
        let dir = brdf::data_dir().join("nbrdf").join("merl");
        let names = brdf::nbrdf::list(&dir).unwrap_or_else(|e| {
            panic!(
                "shared data missing at {} ({e}); set BRDF_DATA_DIR",
                dir.display()
            )
        });
        let mut mine = l.materials.clone();
        mine.sort();
        let mut theirs = names.clone();
        theirs.sort();
        assert_eq!(mine, theirs);
    }
}
