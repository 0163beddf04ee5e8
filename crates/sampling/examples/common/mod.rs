//! What the sampling examples share: argument parsing and the benchmark split (train on the
//! 96 shared MERL materials, test on the 8 Nielsen materials).

use std::time::Instant;

use brdf::nbrdf::{load_dir, Nbrdf};
use sampling::{tabulate_nbrdf_f32, TrainingSet};
use sampling::{GridTable, SampleGrid};

/// Errors of the examples.
pub type Error = Box<dyn std::error::Error>;

/// The value after `name` on the command line, or `default`.
pub fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The grid of `--step H,D,P` (default the full MERL grid).
pub fn grid_arg(args: &[String]) -> Result<SampleGrid, Error> {
    let step: String = arg(args, "--step", "1,1,1".to_string());
    let s: Vec<usize> = step
        .split(',')
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    if s.len() != 3 {
        return Err("--step takes three strides".into());
    }
    Ok(SampleGrid::new(s[0], s[1], s[2])?)
}

/// The benchmark materials on `grid`.
pub struct Benchmark {
    /// The 96 MERL training materials.
    pub training: TrainingSet,
    /// The 8 Nielsen test materials.
    pub test: Vec<Nbrdf>,
    /// The test materials tabulated on the grid.
    pub refs: Vec<GridTable>,
    /// Decoding time, s.
    pub decode_seconds: f64,
}

/// Decodes the benchmark from the shared data directory.
pub fn load_benchmark(grid: SampleGrid) -> Result<Benchmark, Error> {
    let data = brdf::data_dir().join("nbrdf");
    let t0 = Instant::now();
    let training = TrainingSet::from_nbrdf_dir(data.join("merl"), grid)?;
    let test = load_dir(data.join("nielsen"))?;
    let refs: Vec<GridTable> = test
        .iter()
        .map(|m| {
            let v = tabulate_nbrdf_f32(m, grid);
            GridTable::new(grid, v.iter().map(|&x| f64::from(x)).collect())
        })
        .collect::<Result<_, _>>()?;
    Ok(Benchmark {
        training,
        test,
        refs,
        decode_seconds: t0.elapsed().as_secs_f64(),
    })
}
