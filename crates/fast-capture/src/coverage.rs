//! Which table entries a lamp position measures: the (channel, bin) pairs its lit sphere pixels
//! fall in, found by the capture's own sample code on unit signal.

use crate::error::Result;
use binning::{position_samples, BinAssignment, ForwardOptions, Rates, RigGeometry, SphereView};
use rayon::prelude::*;

/// The table entries each candidate lamp position reaches. An entry is
/// `channel · BINS + bin`, the layout of [`brdf::MerlTable::values`] and of the model's vectors.
#[derive(Debug, Clone, PartialEq)]
pub struct Coverage {
    /// Candidate lamp angles, degrees.
    pub angles_deg: Vec<f64>,
    /// Per candidate: the entries it reaches, sorted, without repeats.
    pub entries: Vec<Vec<u32>>,
}

impl Coverage {
    /// The entries each of `angles_deg` reaches with the rig `geometry` seen through `view`:
    /// every sphere pixel the lamp lights within the capture's incidence limit gives one sample
    /// in its Bayer channel, assigned to its bin as the capture assigns it
    /// ([`binning::position_samples`] on a uniform unit signal). Exposure does not enter: a
    /// pixel too dim for the exposures taken is counted as reached.
    pub fn compute(
        view: &SphereView,
        geometry: &dyn RigGeometry,
        angles_deg: &[f64],
        assignment: BinAssignment,
    ) -> Result<Self> {
        let n = view.width * view.height;
        let rate = vec![1.0f32; n];
        let valid = vec![true; n];
        let options = ForwardOptions {
            subtract_ambient: false,
            assignment,
            ..ForwardOptions::default()
        };
        let entries = angles_deg
            .par_iter()
            .map(|&angle| {
                let lamp = geometry.lamp_position(angle);
                let samples = position_samples(
                    view,
                    Rates {
                        rate: &rate,
                        valid: &valid,
                    },
                    &lamp,
                    &[1.0; 3],
                    &options,
                )?;
                let mut e: Vec<u32> = samples.iter().map(|s| s.key).collect();
                e.sort_unstable();
                e.dedup();
                Ok(e)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            angles_deg: angles_deg.to_vec(),
            entries,
        })
    }

    /// Whether each entry of the table (`3 · BINS`) is reached by some candidate.
    pub fn union(&self) -> Vec<bool> {
        let mut m = vec![false; brdf::MATERIAL_DIM];
        for e in self.entries.iter().flatten() {
            m[*e as usize] = true;
        }
        m
    }

    /// Whether each entry is reached by one of the candidates `chosen`.
    pub fn union_of(&self, chosen: &[usize]) -> Vec<bool> {
        let mut m = vec![false; brdf::MATERIAL_DIM];
        for &c in chosen {
            for e in &self.entries[c] {
                m[*e as usize] = true;
            }
        }
        m
    }
}
