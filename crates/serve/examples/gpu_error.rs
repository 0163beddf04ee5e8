//! What the real-time view's reduced grid costs: for each material, its `k`-coefficient
//! projection on a model evaluated as the shader does ([`serve::GpuBasis::eval`]) against
//! the model's full-grid reconstruction of the same coefficients: median |log| and
//! cosine-weighted relative RMS over the MERL table's bins, and the difference of the means of
//! a 256² direct-lighting sphere render (`render::sphere_scene`, 64 samples per pixel).
//!
//! `cargo run --release -p serve --example gpu_error -- MODEL K SPEC [SPEC…]`; the reduced grid
//! is the server's default, or `GPU_GRID=TH,TD,PD` (counts dividing 90, 90, 180).

use render::{render_scene, sphere_scene, Integrator, Material, RenderOptions};
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: gpu_error MODEL K SPEC [SPEC…]".into());
    }
    let model = reduce::Model::load(&args[0])?;
    let k: usize = args[1].parse()?;
    let grid = match std::env::var("GPU_GRID") {
        Ok(s) => {
            let v: Vec<usize> = s.split(',').map(str::parse).collect::<Result<_, _>>()?;
            if v.len() != 3 {
                return Err("GPU_GRID=TH,TD,PD".into());
            }
            serve::GpuGrid {
                theta_h: v[0],
                theta_d: v[1],
                phi_d: v[2],
            }
        }
        Err(_) => serve::GpuGrid::default(),
    };
    let basis = Arc::new(serve::GpuBasis::from_model(&model, grid)?);
    println!(
        "model: {} components; grid {}×{}×{}; texture memory for k = {k}: {:.1} MB (full-grid f32: {:.1} MB)",
        model.components(),
        grid.theta_h,
        grid.theta_d,
        grid.phi_d,
        basis.memory_bytes(k) as f64 / 1048576.0,
        (k + 1) as f64 * 3.0 * brdf::BINS as f64 * 4.0 / 1048576.0
    );
    println!("material,median_abs_log,cosine_weighted_relative_rms,sphere_mean_difference_r,g,b");
    let options = RenderOptions {
        spp: 64,
        integrator: Integrator::Direct,
        ..Default::default()
    };
    for spec in &args[2..] {
        let values = brdf::load(spec)?.tabulate().values();
        let c = model.project_values(&values, k)?;
        let e = serve::gpu_reduction_error(&model, &basis, &c)?;
        let full = brdf::MerlTable::from_values(model.synthesize(&c)?)?;
        let a = render_scene(
            &sphere_scene(Material::new(Arc::new(full)).into(), 256, 256)?,
            &options,
        )?;
        let gpu = basis.brdf(&c);
        let b = render_scene(
            &sphere_scene(Material::new(Arc::new(gpu)).into(), 256, 256)?,
            &options,
        )?;
        let mut d = [0.0; 3];
        for c in 0..3 {
            let sa: f64 = a.pixels().iter().map(|p| p[c] as f64).sum();
            let sb: f64 = b.pixels().iter().map(|p| p[c] as f64).sum();
            d[c] = sb / sa - 1.0;
        }
        println!(
            "{spec},{:.4},{:.4},{:+.4},{:+.4},{:+.4}",
            e.median_abs_log, e.cosine_weighted_relative_rms, d[0], d[1], d[2]
        );
    }
    Ok(())
}
