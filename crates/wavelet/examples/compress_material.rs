//! Compressing a material onto a Common Wavelet Basis and rendering-ready evaluation through
//! the coefficient tree: the `wavelet` crate in one page (thesis §6.1–6.2).
//!
//! `cargo run --release -p wavelet --example compress_material -- [spec] [target] [out.wtree]`
//! (defaults `ggx:alpha=0.2,kd=0.1`, 0.01, a temporary file). Prints the basis size, the
//! compressed size and the error of the evaluated material against the original.

use brdf::{Brdf, MerlTable};
use wavelet::{build_basis, CompressedMaterial, WaveletBrdf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    wavelet::register_spec_resolver();
    let mut args = std::env::args().skip(1);
    let spec = args.next().unwrap_or_else(|| "ggx:alpha=0.2,kd=0.1".into());
    let target: f64 = args.next().map(|t| t.parse()).transpose()?.unwrap_or(0.01);
    let tmp = std::env::temp_dir().join(format!("compress_material_{}.wtree", std::process::id()));
    let out = args.next().map(std::path::PathBuf::from).unwrap_or(tmp);

    let table = brdf::load(&spec)?.tabulate();
    // The basis of a one-material corpus (a real one is built from many: `gantry wavelet basis`).
    let basis = build_basis(std::slice::from_ref(&table), target)?;
    println!(
        "basis: {} coefficients, {:.3}% of a 256³ cube",
        basis.len(),
        100.0 * basis.fraction_of_table()
    );
    let compressed = CompressedMaterial::compress(basis, &table)?;
    compressed.write(&out)?;
    println!(
        "wrote {} ({} bytes)",
        out.display(),
        std::fs::metadata(&out)?.len()
    );
    // Any spec-taking code now accepts `wavelet:<file>`.
    let loaded = brdf::load(&format!("wavelet:{}", out.display()))?;
    let direct = WaveletBrdf::read(&out)?;
    let back = MerlTable::tabulate(&loaded);
    let (a, b) = (table.values(), back.values());
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in a.iter().zip(&b) {
        let (lx, ly) = (brdf::to_log(*x), brdf::to_log(*y));
        num += (lx - ly).powi(2);
        den += (lx - brdf::LOG_FLOOR.ln()).powi(2);
    }
    println!(
        "{} through the tree at the MERL bins: relative log-space error {:.4} (offset ln ε)",
        direct.name(),
        (num / den).sqrt()
    );
    // The basis's own measure: relative L2 error of each reconstructed log channel.
    let original = wavelet::log_channels(&table);
    let reconstructed = compressed.log_channels()?;
    for (c, (o, r)) in original.iter().zip(&reconstructed).enumerate() {
        println!(
            "channel {c}: relative L2 error {:.4} (target {target})",
            wavelet::relative_l2_error(o, r)
        );
    }
    Ok(())
}
