//! Writes a material as `.bsdf` and prints our evaluation at a few direction pairs, for a
//! comparison with a renderer's reader: `cargo run -p rgl-bsdf --example bsdf_probe -- SPEC OUT.bsdf`.
use brdf::Spherical;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (spec, out) = (&args[1], &args[2]);
    let m = brdf::load(spec)?;
    let file = rgl_bsdf::write(m.as_brdf(), &rgl_bsdf::WriteOptions::default())?;
    file.write(out)?;
    let back = rgl_bsdf::RglBsdf::read(out)?;
    for (ti, pi, to, po) in [
        (0.2, 0.0, 0.3, 3.0),
        (0.5, 1.0, 0.5, 4.1),
        (0.9, 0.3, 0.2, 2.0),
        (0.1, 0.0, 1.2, 0.5),
        (1.0, 2.0, 1.0, 5.2),
    ] {
        let (wi, wo) = (
            Spherical::new(ti, pi).to_vector(),
            Spherical::new(to, po).to_vector(),
        );
        let c = back.eval_cos(&wi, &wo);
        let f = m.as_brdf().eval(&wi, &wo).map(|v| v * wo.z);
        println!(
            "{} {} {} {} {} {} {} {} {} {} {} {}",
            wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, c[0], c[1], c[2], f[0], f[1], f[2]
        );
    }
    Ok(())
}
