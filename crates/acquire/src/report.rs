//! What a finished job reports (`DIR/report.json`, `DIR/inverse_report.json`) and the table
//! error against a known material.

use crate::devices::{FaultEvent, FaultKind};
use crate::spec::Backend;
use binning::ImageError;
use brdf::metrics::TableError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `DIR/report.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// Material spec of the job.
    pub material: String,
    /// Simulator or devices.
    pub backend: Backend,
    /// Where the geometry came from.
    pub geometry: String,
    /// Lamp positions.
    pub positions: usize,
    /// Wall-clock seconds per stage.
    pub wall_seconds: Stages,
    /// Simulated capture clock, seconds (simulator only).
    pub simulated_capture_s: Option<f64>,
    /// Simulated capture clock, hours (simulator only).
    pub simulated_capture_hours: Option<f64>,
    /// BRDF samples binned.
    pub samples_total: u64,
    /// Median samples per position.
    pub samples_per_position_median: usize,
    /// Share of bins × channels holding a value.
    pub coverage: f64,
    /// Passes over the sample files the memory budget needed.
    pub binning_passes: usize,
    /// Absolute scale per channel.
    pub lamp_constant: [f64; 3],
    /// Hot photosites found in the dark frame.
    pub hot_pixels: usize,
    /// Each position re-rendered from the table against its HDR image.
    pub validation: Vec<PositionValidation>,
    /// Median over positions of the validation's median |log| error.
    pub validation_median_abs_log: f64,
    /// Faults met and handled.
    pub faults: FaultSummary,
    /// Error against the true material (simulator only).
    pub truth_table_error: Option<TableError>,
    /// Error against the reciprocity-symmetrised truth, ½(f(φd) + f(φd + π)): what a reciprocal
    /// measurement can see when the true material (a neural fit) is not exactly reciprocal.
    pub reciprocal_truth_error: Option<TableError>,
}

/// Wall-clock seconds of the job's stages.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Stages {
    /// Devices, calibration, dark frame, ambient, lamp constant.
    pub setup: f64,
    /// The positions (or, for a re-bin, the re-merge of stored frames).
    pub capture: f64,
    /// Robust binning into the table.
    pub binning: f64,
    /// Re-rendering every position from the table.
    pub validation: f64,
    /// The whole job.
    pub total: f64,
}

/// Validation of one position.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PositionValidation {
    /// Position index.
    pub index: usize,
    /// Lamp angle, degrees.
    pub angle_deg: f64,
    /// Re-rendered against measured.
    #[serde(flatten)]
    pub error: ImageError,
}

/// Faults of a job.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct FaultSummary {
    /// Faults met.
    pub total: usize,
    /// Series taken again.
    pub repeated_series: usize,
    /// Faults per kind.
    pub by_kind: BTreeMap<FaultKind, usize>,
    /// Every fault, with its position.
    pub events: Vec<PositionFault>,
}

/// A fault met at a position.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PositionFault {
    /// Position index.
    pub position: usize,
    /// The fault.
    #[serde(flatten)]
    pub event: FaultEvent,
}

/// `DIR/inverse_report.json`: the inverse-mapped table (thesis §3.5) against the forward-binned
/// one and, on the simulator, against the truth.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct InverseReport {
    /// Positions used.
    pub positions: usize,
    /// Coverage of `brdf_inverse.binary`: the bins forward binning also reached.
    pub coverage: f64,
    /// Coverage of `brdf_inverse_all.binary`: every bin some position reaches.
    pub coverage_all: f64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// Against the forward-binned table.
    pub versus_forward: TableError,
    /// Against the true material (simulator only).
    pub truth_table_error: Option<TableError>,
    /// Against the reciprocity-symmetrised truth.
    pub reciprocal_truth_error: Option<TableError>,
    /// `brdf_inverse_all.binary` against the truth.
    pub all_bins_truth_table_error: Option<TableError>,
    /// `brdf_inverse_all.binary` against the symmetrised truth.
    pub all_bins_reciprocal_truth_error: Option<TableError>,
}

/// Tabulation of ½(f(θh, θd, φd) + f(θh, θd, φd + π)): the reciprocal part of a material.
pub fn reciprocal_table(material: &dyn brdf::Brdf) -> brdf::MerlTable {
    struct Symmetrised<'a>(&'a dyn brdf::Brdf);
    impl brdf::Brdf for Symmetrised<'_> {
        fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> brdf::Rgb {
            let (a, b) = (self.0.eval(wi, wo), self.0.eval(wo, wi));
            [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
        }
        fn eval_half_diff(&self, hd: &brdf::HalfDiff) -> brdf::Rgb {
            let (a, b) = (
                self.0.eval_half_diff(hd),
                self.0.eval_half_diff(&hd.swapped()),
            );
            [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
        }
        fn name(&self) -> String {
            self.0.name()
        }
    }
    brdf::MerlTable::tabulate(&Symmetrised(material))
}
