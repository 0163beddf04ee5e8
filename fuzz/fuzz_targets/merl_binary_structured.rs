//! MERL `.binary` tables with a valid header and full length around a mutated body, so that
//! the fuzzer reaches what comes after the size check: the value checks, the table's lookups
//! (with missing bins, negative values and huge ones) and the albedo quadrature. The input is a list of
//! patches (a bin index and a value each) over a constant table; the first byte picks the
//! interpolation.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

const VALUES: usize = 3 * 90 * 90 * 180;

fn base() -> &'static [u8] {
    static BASE: OnceLock<Vec<u8>> = OnceLock::new();
    BASE.get_or_init(|| {
        let mut b = Vec::with_capacity(12 + 8 * VALUES);
        for d in [90i32, 90, 180] {
            b.extend_from_slice(&d.to_le_bytes());
        }
        for _ in 0..VALUES {
            b.extend_from_slice(&0.25f64.to_le_bytes());
        }
        b
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, patches)) = data.split_first() else {
        return;
    };
    let mut bytes = base().to_vec();
    for p in patches.chunks_exact(12) {
        let i = u32::from_le_bytes([p[0], p[1], p[2], p[3]]) as usize % VALUES;
        bytes[12 + 8 * i..20 + 8 * i].copy_from_slice(&p[4..12]);
    }
    let Ok(mut table) = brdf::merl::parse(&bytes, std::path::Path::new("fuzz.binary")) else {
        return;
    };
    if mode & 1 == 1 {
        table = table.with_interpolation(brdf::table::Interpolation::Trilinear);
    }
    // lookups in directions spread over the hemisphere, and at the patched bins' angles
    use brdf::Brdf;
    for k in 0..64u32 {
        let t = k as f64 / 64.0;
        let wi = brdf::Vec3::new((6.0 * t).sin() * 0.8, (6.0 * t).cos() * 0.3, 0.52);
        let wo = brdf::Vec3::new(-0.4 * t, 0.7 - t, 0.6);
        let _ = table.eval(&wi.normalize(), &wo.normalize());
    }
    let _ = brdf::summary::directional_albedo(&table, 0.3, 4, 4);
});
