//! Render scene TOML. The parser, not the data loader, is under test: the resolver gives analytic
//! material specs only (a `merl:` or `nbrdf:` material would decode a 1.5 M-bin table, seconds of
//! legitimate work that the 1 s limit would call a hang), and mesh paths point nowhere.
#![no_main]
use libfuzzer_sys::fuzz_target;
use render::material::MaterialResolver;
use std::sync::Arc;

struct AnalyticOnly;

impl MaterialResolver for AnalyticOnly {
    fn spec(&self, spec: &str) -> render::Result<Arc<dyn brdf::Brdf>> {
        match brdf::spec::parse(spec) {
            Ok(brdf::spec::MaterialSpec::Analytic { .. }) => {
                render::scene_file::SpecResolver.spec(spec)
            }
            _ => Err(render::RenderError::Scene(format!(
                "{spec}: only analytic specs in this target"
            ))),
        }
    }
}

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = render::scene_file::parse_scene(
            text,
            std::path::Path::new("/nonexistent-fuzz-dir"),
            &AnalyticOnly,
        );
    }
});
