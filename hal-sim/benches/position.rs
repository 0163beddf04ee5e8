//! Full-resolution simulation time of one lamp position with 18 exposures (40 µs … 20 s).
//!
//! `cargo bench -p hal-sim --bench position [-- <material spec>]`; the default material is the
//! neural BRDF `merl:alumina-oxide` from the shared data (falls back to `phong` when absent).

use gantry_hal::Rig;
use hal_sim::{SimConfig, SimRig};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// CPU time (user + system) of this process, seconds, from /proc/self/stat (Linux).
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let after = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn main() {
    let spec = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .unwrap_or_else(|| "merl:alumina-oxide".into());
    let material: Arc<dyn brdf::Brdf> = match brdf::load(&spec) {
        Ok(m) => Arc::new(m),
        Err(e) => {
            eprintln!("{spec}: {e}; using phong");
            Arc::new(brdf::load("phong:kd=0.3,ks=0.5,n=80").expect("phong spec"))
        }
    };
    let threads = rayon::current_num_threads();
    let mut cfg = SimConfig::default();
    cfg.lamp.warm_up_s = 0.0;
    let t0 = Instant::now();
    let sim = SimRig::new(cfg, material).expect("simulated rig");
    let setup = t0.elapsed();
    let truth = sim.truth();
    println!(
        "material {} | sensor {}x{} | sphere pixels {} | threads {threads} | setup {:.3} s",
        truth.material,
        truth.camera.width,
        truth.camera.height,
        sim.scene().sphere_pixel_count(),
        setup.as_secs_f64()
    );
    let long = Duration::from_secs(3600);
    let mut rig: Rig = sim.rig();
    rig.turntable.home(long).unwrap();
    rig.lamp.set_on(true).unwrap();
    rig.lamp.wait_stable(long).unwrap();
    let r = (20.0f64 / 40e-6).powf(1.0 / 17.0);
    let exposures: Vec<f64> = (0..18).map(|k| 40e-6 * r.powi(k)).collect();
    let mut times = Vec::new();
    let mut cpus = Vec::new();
    for (p, angle) in [10.0, 60.0, 120.0, 150.0, 164.5].into_iter().enumerate() {
        let t = Instant::now();
        let c0 = cpu_seconds();
        rig.turntable.move_to(angle, long).unwrap();
        let mut first = None;
        for &e in &exposures {
            rig.camera.set_exposure(e).unwrap();
            let f = rig.camera.capture(long).unwrap();
            first.get_or_insert(t.elapsed());
            std::hint::black_box(&f);
        }
        let dt = t.elapsed();
        let cpu = c0
            .zip(cpu_seconds())
            .map(|(a, b)| b - a)
            .unwrap_or(f64::NAN);
        println!(
            "position {p} ({angle:>5.1}°): wall {:.3} s for 18 exposures (render + first frame {:.3} s), CPU {cpu:.2} s",
            dt.as_secs_f64(),
            first.unwrap().as_secs_f64()
        );
        times.push(dt.as_secs_f64());
        cpus.push(cpu);
    }
    // The noise generator alone: one full frame from cached rate maps.
    let scene = sim.scene();
    let lamp = scene.lamp_rate_e(90.0);
    let base = scene.stray_rate_e();
    let mut per_frame = Vec::new();
    for (k, &e) in exposures.iter().enumerate() {
        let c0 = cpu_seconds();
        let t = Instant::now();
        let f = scene
            .expose(&lamp, 1.0, &base, e, 25.0, 10_000 + k as u64)
            .unwrap();
        std::hint::black_box(&f);
        let cpu = c0
            .zip(cpu_seconds())
            .map(|(a, b)| b - a)
            .unwrap_or(f64::NAN);
        per_frame.push((t.elapsed().as_secs_f64(), cpu));
    }
    let wall: f64 = per_frame.iter().map(|p| p.0).sum::<f64>() / 18.0;
    let cpu: f64 = per_frame.iter().map(|p| p.1).sum::<f64>() / 18.0;
    let npx = (truth.camera.width * truth.camera.height) as f64;
    println!(
        "noise generation alone: wall {:.1} ms/frame, CPU {:.1} ms/frame ({:.1} ns CPU per pixel)",
        wall * 1e3,
        cpu * 1e3,
        cpu / npx * 1e9
    );
    times.sort_by(|a, b| a.total_cmp(b));
    cpus.sort_by(|a, b| a.total_cmp(b));
    println!(
        "per-position wall time: median {:.3} s, max {:.3} s (target ≤ 1 s on 2 cores); \
         CPU time median {:.2} s (= {:.3} s of wall time on 2 idle cores)",
        times[times.len() / 2],
        times[times.len() - 1],
        cpus[cpus.len() / 2],
        cpus[cpus.len() / 2] / 2.0
    );
}
