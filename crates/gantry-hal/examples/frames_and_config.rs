//! The `gantry-hal` data types without hardware: a rig configuration parsed from TOML, a raw
//! Bayer frame packed and unpacked in the camera's formats, and what opening a real rig says
//! when its devices (or the features that drive them) are absent.
//!
//! `cargo run -p gantry-hal --example frames_and_config [-- rig.toml]`
//! (default `docs/rig.example.toml`).

use gantry_hal::{pack_bayer10, unpack_bayer10, Bayer10Format, BayerFrame, BayerPattern};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/rig.example.toml").into()
    });
    let cfg = gantry_hal::RigConfig::load(std::path::Path::new(&path))?;
    cfg.validate()?;
    println!("{path}: backend {:?}", cfg.backend);

    let (w, h) = (8, 4);
    let data: Vec<u16> = (0..w * h).map(|i| (i * 31 % 1024) as u16).collect();
    let frame = BayerFrame::new(w, h, 10, BayerPattern::Rggb, data, 0.02, 0.0, 24.5, 1)?;
    for format in [
        Bayer10Format::MipiPacked,
        Bayer10Format::Lsb16,
        Bayer10Format::Msb16,
    ] {
        let raw = pack_bayer10(format, &frame.data, w, h)?;
        let back = unpack_bayer10(format, &raw, w, h, None)?;
        assert_eq!(back, frame.data);
        println!(
            "{format:?}: {} bytes for {} samples, round trip exact",
            raw.len(),
            w * h
        );
    }
    // No devices here: the first missing one is named (or the feature that would drive it).
    match gantry_hal::open_real_rig(&cfg) {
        Ok(_) => println!("a real rig answered"),
        Err(e) => println!("open_real_rig: {e}"),
    }
    Ok(())
}
