//! Directional albedo of a material and of its `.bsdf` file at a few incident elevations:
//! `cargo run --release -p rgl-bsdf --example albedo_check -- SPEC [NDF_RES] [RES] [THETA_I] [BROAD]`.
use brdf::{Spherical, Vec3};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let m = brdf::load(&args[1]).unwrap();
    let num = |i: usize, d: f64| args.get(i).map(|s| s.parse().unwrap()).unwrap_or(d);
    let o = rgl_bsdf::WriteOptions {
        ndf_resolution: num(2, 64.0) as usize,
        resolution: num(3, 32.0) as usize,
        vndf_resolution: num(3, 32.0) as usize,
        theta_i: num(4, 16.0) as usize,
        broad_share: num(5, 0.3),
        ..Default::default()
    };
    let back = rgl_bsdf::RglBsdf::from_tensor(&rgl_bsdf::write(m.as_brdf(), &o).unwrap()).unwrap();
    for theta_i in [0.1, 0.5, 0.9, 1.2] {
        let wi = Spherical::new(theta_i, 0.3).to_vector();
        let n = 1024;
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        for i in 0..n {
            for j in 0..n {
                let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let (r, phi) = (u.sqrt(), std::f64::consts::TAU * v);
                let wo = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt());
                let (f, g) = (m.as_brdf().eval(&wi, &wo), back.eval_cos(&wi, &wo));
                for c in 0..3 {
                    a[c] += f[c];
                    b[c] += g[c] / wo.z;
                }
            }
        }
        let k = std::f64::consts::PI / (n * n) as f64;
        println!(
            "θi {theta_i}: truth {:?} file {:?} ({:+.2} %)",
            a.map(|x| (x * k * 1e4).round() / 1e4),
            b.map(|x| (x * k * 1e4).round() / 1e4),
            (b[1] / a[1] - 1.0) * 100.0
        );
    }
}
