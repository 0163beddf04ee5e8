//! Variance of the reflected-radiance estimator (thesis A.5) with cosine-weighted sampling versus
//! tabulated BRDF importance sampling (A.2.4), per material, at equal sample counts.
//!
//! `cargo run --release -p render --example variance_factors -- [samples] [materials...]`

use brdf::{Brdf, Rgb, Vec3};
use rand::SeedableRng;
use render::estimate_reflected_radiance;
use render::SampleRng;
use render::SpecResolver;
use render::*;
use std::sync::Arc;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let mut names: Vec<String> = args.iter().skip(2).cloned().collect();
    if names.is_empty() {
        names = ["chrome", "nickel", "blue-acrylic"]
            .map(String::from)
            .to_vec();
    }
    let env = EnvironmentMap::procedural_probe(512, 256, 1).unwrap();
    let uniform_light = |_: &Vec3| -> Rgb { [1.0; 3] };
    // local frame with the normal along world +y
    let env_light = |w: &Vec3| -> Rgb { env.radiance(&Vec3::new(w.x, w.z, -w.y)) };
    let thetas = [5.0f64, 20.0, 35.0, 50.0, 65.0, 80.0];
    println!("samples per direction: {n}; θr = {thetas:?} degrees");
    println!("| material | lighting | Var cosine / Var IS (inversion) | Var cosine / Var IS (rejection) | Var uniform / Var IS (inversion) |");
    println!("|---|---|---|---|---|");
    for name in &names {
        let spec = format!("merl:{name}");
        let t0 = Instant::now();
        let brdf = SpecResolver.spec(&spec).unwrap();
        let table: Arc<dyn Brdf> = SpecResolver.tabulated(&spec, &brdf).unwrap().unwrap();
        let t1 = Instant::now();
        let imp = Arc::new(BrdfImportance::build(
            table.as_ref(),
            ImportanceResolution::default(),
        ));
        let t2 = Instant::now();
        eprintln!(
            "{name}: tabulate {:.2}s, importance tables {:.2}s ({:.1} MB)",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            imp.memory_bytes() as f64 / 1e6
        );
        let samplers = [
            DirectionSampler::Cosine,
            DirectionSampler::Importance {
                table: imp.clone(),
                variant: PhiSampling::Inversion,
            },
            DirectionSampler::Importance {
                table: imp.clone(),
                variant: PhiSampling::Rejection,
            },
            DirectionSampler::Uniform,
        ];
        for (label, light) in [
            ("uniform L=1", &uniform_light as &dyn Fn(&Vec3) -> Rgb),
            ("procedural probe", &env_light),
        ] {
            let mut var = [0.0; 4];
            for (s, sampler) in samplers.iter().enumerate() {
                let mut rng = SampleRng::seed_from_u64(42 + s as u64);
                for &deg in &thetas {
                    let th = deg.to_radians();
                    for phi in [0.0f64, 2.0] {
                        let wo = Vec3::new(th.sin() * phi.cos(), th.sin() * phi.sin(), th.cos());
                        let st = estimate_reflected_radiance(
                            table.as_ref(),
                            sampler,
                            &wo,
                            light,
                            n,
                            &mut rng,
                        );
                        var[s] += st.total_variance();
                    }
                }
            }
            println!(
                "| {name} | {label} | {:.1} | {:.1} | {:.1} |",
                var[0] / var[1],
                var[0] / var[2],
                var[3] / var[1]
            );
        }
    }
}
