//! Lists of Rusinkiewicz angles read from CSV text.

use crate::coords::HalfDiff;

/// A malformed angle list; the message names the source and the line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{source_name}: {reason}")]
pub struct AnglesError {
    /// The file (or `-` for standard input) the text came from.
    pub source_name: String,
    /// What is wrong, with the line number where there is one.
    pub reason: String,
}

/// Parses a list of Rusinkiewicz angles from CSV text: a header naming the columns `theta_h`,
/// `theta_d` and `phi_d` (radians; in any order, other columns ignored), then one row per point
/// (blank lines skipped). `source_name` names the text in errors. Every value must be a finite
/// number.
///
/// # Examples
///
/// ```
/// let points = brdf::parse_csv("theta_h,theta_d,phi_d\n0.1,0.2,1.5\n\n0,0,0\n", "in.csv")?;
/// assert_eq!(points.len(), 2);
/// assert_eq!((points[0].theta_h, points[0].theta_d, points[0].phi_d), (0.1, 0.2, 1.5));
/// assert!(brdf::parse_csv("theta_h,theta_d\n0,0\n", "bad.csv").is_err());
/// # Ok::<(), brdf::AnglesError>(())
/// ```
pub fn parse_csv(text: &str, source_name: &str) -> Result<Vec<HalfDiff>, AnglesError> {
    let err = |reason: String| AnglesError {
        source_name: source_name.to_string(),
        reason,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| err("empty file, expected header theta_h,theta_d,phi_d".into()))?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |n: &str| {
        cols.iter()
            .position(|c| *c == n)
            .ok_or_else(|| err(format!("header lacks column '{n}' (found '{header}')")))
    };
    let (ih, id, ip) = (find("theta_h")?, find("theta_d")?, find("phi_d")?);
    let mut out = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != cols.len() {
            return Err(err(format!(
                "line {}: {} fields, header has {}",
                i + 1,
                fields.len(),
                cols.len()
            )));
        }
        let num = |k: usize, col: &str| -> Result<f64, AnglesError> {
            let v: f64 = fields[k].parse().map_err(|_| {
                err(format!(
                    "line {}: {col} '{}' is not a number",
                    i + 1,
                    fields[k]
                ))
            })?;
            if !v.is_finite() {
                return Err(err(format!("line {}: {col} is not finite", i + 1)));
            }
            Ok(v)
        };
        out.push(HalfDiff::isotropic(
            num(ih, "theta_h")?,
            num(id, "theta_d")?,
            num(ip, "phi_d")?,
        ));
    }
    Ok(out)
}
