//! What `gantry model report` does: load a model file and write its CSV tables and PNG plots.
//!
//! `cargo run --release -p reduce --example model_report -- MODEL.bin OUT_DIR`

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, out] = args.as_slice() else {
        return Err("usage: model_report MODEL.bin OUT_DIR".into());
    };
    let t = Instant::now();
    let m = reduce::Model::load(model)?;
    println!(
        "loaded {model}: {} materials, {} components, chart: {} ({:.1} s)",
        m.names.len(),
        m.components(),
        m.chart.as_ref().map_or("none".to_string(), |c| format!(
            "{}-D in {} coordinates",
            c.dim,
            c.charts.ambient_dim()
        )),
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let rep = reduce::write_report(&m, out)?;
    println!("report written in {:.1} s:", t.elapsed().as_secs_f64());
    for f in &rep.files {
        println!("  {}", f.display());
    }
    for (d, e) in rep.chart_errors.iter().enumerate() {
        println!("charting error d={}: {e:.5}", d + 1);
    }
    Ok(())
}
