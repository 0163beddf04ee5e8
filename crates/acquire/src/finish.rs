//! After the positions: robust binning into the table, validation by re-rendering every position
//! from it, the report, and optionally the inverse mapping (thesis §3.5). Shared by a capture and
//! a re-bin.

use crate::error::{AcquireError, Result};
use crate::layout::{read_json, write_atomic, write_json, JobDir};
use crate::position::{PositionContext, PositionLog};
use crate::report::{
    reciprocal_table, FaultSummary, InverseReport, PositionFault, PositionValidation, Report,
    Stages,
};
use crate::spec::{Backend, JobRecord};
use binning::{compare, rerender};
use binning::{BinnedTable, Rates};
use brdf::metrics::table_error;
use std::path::PathBuf;
use std::time::Instant;

/// The true table of a simulated job and its reciprocity-symmetrised version.
pub type Truth = (brdf::MerlTable, brdf::MerlTable);

/// The true table of `material` (a material spec) and its reciprocity-symmetrised version.
pub fn material_truth(material: &str) -> Result<Truth> {
    let m = brdf::load(material)?;
    Ok((m.tabulate(), reciprocal_table(m.as_brdf())))
}

/// The truth of the recorded job when it ran on the simulator (its material).
pub fn truth_of(record: &JobRecord) -> Result<Option<Truth>> {
    if record.backend != Backend::Sim {
        return Ok(None);
    }
    material_truth(&record.material).map(Some)
}

/// Smallest budget for the values of one binning pass: below it the passes (one read of every
/// position file each) would multiply.
const MIN_VALUE_BYTES: usize = 16 << 20;

/// The binning's value budget within a job budget of `memory_mb` MiB: what remains after the
/// memory the job already holds (`resident`, counted from the job's start) and the binning's
/// fixed tables ([`binning::FIXED_BYTES`]).
fn value_budget(memory_mb: usize, resident: usize) -> Result<usize> {
    let job = memory_mb << 20;
    let values = job.saturating_sub(resident + binning::FIXED_BYTES);
    if values < MIN_VALUE_BYTES {
        return Err(AcquireError::InvalidJob(format!(
            "memory budget of {memory_mb} MiB is too small for binning: the job holds {} MiB \
             and the binning tables need {} MiB, which leaves less than the {} MiB one pass of \
             values needs",
            resident >> 20,
            binning::FIXED_BYTES >> 20,
            MIN_VALUE_BYTES >> 20
        )));
    }
    Ok(values)
}

/// Bins every position's samples into the table (stored by [`store_binned`]).
///
/// `memory_mb` is the job's budget: the values of a pass get what is left after the memory the
/// job has added to the process by the time binning starts (resident memory above
/// `resident_at_start`, what the process held before the job, such as a Python interpreter) and
/// the binning's fixed tables, so that the job's peak stays within it (an error when less than
/// 16 MiB would be left).
pub fn bin_positions(
    dir: &JobDir,
    record: &JobRecord,
    memory_mb: usize,
    resident_at_start: usize,
) -> Result<BinnedTable> {
    let files: Vec<PathBuf> = (0..record.angles_deg.len())
        .map(|i| dir.samples(i))
        .collect();
    if let Some(f) = files.iter().find(|f| !f.exists()) {
        return Err(AcquireError::Incomplete(f.clone()));
    }
    let resident = brdf::resident_bytes()
        .map(|b| b as usize)
        .unwrap_or(0)
        .saturating_sub(resident_at_start);
    let budget_bytes = value_budget(memory_mb, resident)?;
    tracing::info!(
        resident_mib = resident >> 20,
        values_mib = budget_bytes >> 20,
        "binning within a job budget of {memory_mb} MiB"
    );
    let binned = binning::bin_samples(
        &binning::SampleFiles::new(files),
        &binning::BinningOptions {
            budget_bytes,
            ..Default::default()
        },
    )?;
    Ok(binned)
}

/// The binning's checkpoint besides the table and the counts: written last, so that its
/// presence means both are whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
struct BinningSeal {
    /// Passes over the sample files binning needed.
    passes: usize,
    /// Samples binned.
    samples: u64,
}

/// Writes the binned table: `brdf.binary`, `counts.bin` and, last, the binning's checkpoint
/// `binning.json` (each atomically).
pub fn store_binned(dir: &JobDir, binned: &BinnedTable) -> Result<()> {
    brdf::merl::write(dir.table(), &binned.table)?;
    let counts: Vec<u8> = binned.counts.iter().flat_map(|c| c.to_le_bytes()).collect();
    write_atomic(&dir.counts(), &counts)?;
    write_json(
        &dir.binning(),
        &BinningSeal {
            passes: binned.passes,
            samples: binned.total_samples(),
        },
    )
}

/// Reads the binned table a finished binning stored ([`store_binned`]); an error when its
/// checkpoint is missing or the files disagree with it.
pub fn load_binned(dir: &JobDir) -> Result<BinnedTable> {
    let seal: BinningSeal = read_json(&dir.binning())?;
    let table = brdf::merl::read(dir.table())?;
    let path = dir.counts();
    let bytes = std::fs::read(&path).map_err(crate::error::io(&path))?;
    let malformed = |reason: String| AcquireError::Malformed {
        path: path.clone(),
        reason,
    };
    if bytes.len() != 4 * 3 * brdf::BINS {
        return Err(malformed(format!("{} bytes", bytes.len())));
    }
    let counts: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let binned = BinnedTable {
        table,
        counts,
        passes: seal.passes,
    };
    if binned.total_samples() != seal.samples {
        return Err(malformed(format!(
            "{} samples, the binning recorded {}",
            binned.total_samples(),
            seal.samples
        )));
    }
    Ok(binned)
}

/// Re-renders every position from `table` and compares it with its HDR image; writes the
/// contact sheet of eight positions.
pub fn validate_positions(
    dir: &JobDir,
    record: &JobRecord,
    ctx: &PositionContext<'_>,
    table: &brdf::MerlTable,
    pattern: gantry_hal::BayerPattern,
) -> Result<Vec<PositionValidation>> {
    let n = record.angles_deg.len();
    let mut validation = Vec::with_capacity(n);
    let mut sheet_rows = Vec::new();
    let sheet_every = n.div_ceil(8).max(1);
    for (i, &angle) in record.angles_deg.iter().enumerate() {
        let hdr_file = hdr::read_exr(&dir.hdr(i))?;
        let valid = hdr_file
            .valid
            .clone()
            .unwrap_or_else(|| vec![true; hdr_file.radiance.len()]);
        let lamp = ctx.calibration.lamp_position(angle);
        let measured = Rates {
            rate: &hdr_file.radiance,
            valid: &valid,
        };
        // The table holds reflection only: add back the ambient signal the binning removed.
        let ambient = match ctx.ambient {
            Some(a) => a,
            None => binning::ambient_rate(ctx.view, measured, &lamp)?,
        };
        let mut rendered = rerender(ctx.view, table, &lamp, &ctx.lamp_constant, ctx.assignment);
        for (r, p) in rendered.iter_mut().zip(&ctx.view.pixels) {
            *r += ambient[p.channel as usize] as f32;
        }
        let error = compare(ctx.view, &rendered, measured)?;
        validation.push(PositionValidation {
            index: i,
            angle_deg: angle,
            error,
        });
        if i % sheet_every == 0 {
            let mut meas = vec![f32::NAN; ctx.view.width * ctx.view.height];
            for p in &ctx.view.pixels {
                let k = p.index as usize;
                meas[k] = if valid[k] {
                    hdr_file.radiance[k]
                } else {
                    f32::NAN
                };
            }
            sheet_rows.push(binning::SheetRow {
                measured: meas,
                rendered: binning::to_mosaic(ctx.view, &rendered),
            });
        }
    }
    let sheet = binning::contact_sheet(
        ctx.view,
        &sheet_rows,
        move |x, y| pattern.channel_at(x, y),
        4.0,
    );
    if sheet.width > 0 {
        write_png(&dir.contact_sheet(), &sheet)?;
    }
    Ok(validation)
}

/// Summarises the position logs' faults.
pub fn fault_summary(logs: &[PositionLog]) -> FaultSummary {
    let mut faults = FaultSummary::default();
    for l in logs {
        faults.repeated_series += l.series_attempts.saturating_sub(1);
        for f in &l.faults {
            faults.total += 1;
            *faults.by_kind.entry(f.kind).or_default() += 1;
            faults.events.push(PositionFault {
                position: l.index,
                event: f.clone(),
            });
        }
    }
    faults
}

/// Assembles the report (`report.json`) from the binned table, the validation and the
/// position logs.
#[allow(clippy::too_many_arguments)]
pub fn report_of(
    dir: &JobDir,
    record: &JobRecord,
    ctx: &PositionContext<'_>,
    binned: &BinnedTable,
    validation: Vec<PositionValidation>,
    truth: Option<&Truth>,
    mut stages: Stages,
    t_start: Instant,
) -> Result<Report> {
    let n = record.angles_deg.len();
    let logs: Vec<PositionLog> = (0..n)
        .map(|i| read_json(&dir.log(i)))
        .collect::<Result<_>>()?;
    let mut per_pos: Vec<usize> = logs.iter().map(|l| l.samples).collect();
    per_pos.sort_unstable();
    let mut vmed: Vec<f64> = validation.iter().map(|v| v.error.median_abs_log).collect();
    vmed.sort_by(|a, b| a.total_cmp(b));
    let sim_total: f64 = logs.iter().map(|l| l.sim_time_s).sum();
    let simulated = record.backend == Backend::Sim;
    stages.total = t_start.elapsed().as_secs_f64();
    let report = Report {
        material: record.material.clone(),
        backend: record.backend,
        geometry: if let Some(fit) = ctx.calibration.fit {
            if fit.dropped_target_images == 0 {
                "calibrated".into()
            } else {
                format!(
                    "calibrated from {} target images ({} dropped: board not found whole)",
                    fit.target_images, fit.dropped_target_images
                )
            }
        } else {
            "simulator truth or given file".into()
        },
        positions: n,
        wall_seconds: stages,
        simulated_capture_s: simulated.then_some(sim_total),
        simulated_capture_hours: simulated.then_some(sim_total / 3600.0),
        samples_total: binned.total_samples(),
        samples_per_position_median: per_pos.get(per_pos.len() / 2).copied().unwrap_or(0),
        coverage: binned.coverage(),
        binning_passes: binned.passes,
        lamp_constant: ctx.lamp_constant,
        hot_pixels: ctx.defects.hot_count(),
        validation_median_abs_log: vmed.get(vmed.len() / 2).copied().unwrap_or(f64::NAN),
        validation,
        faults: fault_summary(&logs),
        truth_table_error: truth.map(|(t, _)| table_error(&binned.table, t)),
        reciprocal_truth_error: truth.map(|(_, r)| table_error(&binned.table, r)),
    };
    if let Some(e) = &report.truth_table_error {
        tracing::info!(
            median = e.median_abs_log,
            p90 = e.p90_abs_log,
            coverage = report.coverage,
            "table error against the true material"
        );
    }
    Ok(report)
}

/// The inverse mapping (thesis §3.5) over the stored HDR images: writes
/// `brdf_inverse.binary` (the bins forward binning reached) and `brdf_inverse_all.binary` (every
/// bin reached); its report is `inverse_report.json`.
pub fn inverse_mapping(
    dir: &JobDir,
    record: &JobRecord,
    ctx: &PositionContext<'_>,
    truth: Option<&Truth>,
) -> Result<InverseReport> {
    let t0 = Instant::now();
    let opts = binning::InverseOptions::default();
    let mut positions = Vec::with_capacity(record.angles_deg.len());
    for (i, &angle) in record.angles_deg.iter().enumerate() {
        let file = hdr::read_exr(&dir.hdr(i))?;
        let valid = file
            .valid
            .clone()
            .unwrap_or_else(|| vec![true; file.radiance.len()]);
        let rates = Rates {
            rate: &file.radiance,
            valid: &valid,
        };
        let mut p = binning::InversePosition::new(ctx.calibration, ctx.view, angle, rates, &opts)?;
        if let Some(a) = ctx.ambient {
            p.ambient = a;
        }
        positions.push(p);
    }
    let filled = binning::fill_table(
        ctx.calibration,
        ctx.view,
        &positions,
        &ctx.lamp_constant,
        &opts,
    )?;
    // Quality guard: bins that no pixel's own configuration reached (the forward table has no
    // sample there) lie at the specular peak or at grazing angles, where interpolating between
    // pixels does not resolve the BRDF; they are kept only in brdf_inverse_all.binary.
    let forward = brdf::merl::read(dir.table())?;
    let mut guarded = filled.table.clone();
    for c in 0..3 {
        for b in 0..brdf::BINS {
            if !forward.is_valid(c, b) {
                guarded.set(c, b, -1.0);
            }
        }
    }
    brdf::merl::write(dir.root().join("brdf_inverse.binary"), &guarded)?;
    brdf::merl::write(dir.root().join("brdf_inverse_all.binary"), &filled.table)?;
    let covered = |t: &brdf::MerlTable| {
        (0..3)
            .map(|c| (0..brdf::BINS).filter(|&b| t.is_valid(c, b)).count())
            .sum::<usize>() as f64
            / (3 * brdf::BINS) as f64
    };
    let report = InverseReport {
        positions: positions.len(),
        coverage: covered(&guarded),
        coverage_all: filled.coverage(),
        wall_seconds: t0.elapsed().as_secs_f64(),
        versus_forward: table_error(&guarded, &forward),
        truth_table_error: truth.map(|(t, _)| table_error(&guarded, t)),
        reciprocal_truth_error: truth.map(|(_, r)| table_error(&guarded, r)),
        all_bins_truth_table_error: truth.map(|(t, _)| table_error(&filled.table, t)),
        all_bins_reciprocal_truth_error: truth.map(|(_, r)| table_error(&filled.table, r)),
    };
    Ok(report)
}

fn write_png(path: &std::path::Path, img: &binning::Rgb8Image) -> Result<()> {
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, img.data.clone())
        .ok_or_else(|| AcquireError::InvalidJob("contact sheet buffer of the wrong size".into()))?;
    let mut bytes = Vec::new();
    buf.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| AcquireError::Malformed {
        path: path.to_path_buf(),
        reason: format!("PNG encoding: {e}"),
    })?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_values_get_what_the_process_and_the_fixed_tables_leave() {
        let fixed = binning::FIXED_BYTES;
        let resident = 100 << 20;
        let v = value_budget(512, resident).unwrap();
        assert_eq!(v + resident + fixed, 512 << 20);
        // too small a job budget is refused, naming what the memory holds
        let err = value_budget(200, resident).unwrap_err().to_string();
        assert!(
            err.contains("too small") && err.contains("100 MiB"),
            "{err}"
        );
        assert!(value_budget(0, 0).is_err());
    }

    #[test]
    fn this_process_reports_its_resident_memory_where_the_system_tells() {
        if cfg!(target_os = "linux") {
            let r = brdf::resident_bytes()
                .map(|b| b as usize)
                .expect("VmRSS on Linux");
            assert!(r > 1 << 20 && r < 1 << 40, "{r}");
        }
    }
}
