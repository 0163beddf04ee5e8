//! `gantry render`: scene files and the thesis's figure types (the `render` crate's job).

use anyhow::Result;
use render::RenderJob;
use std::sync::Arc;

use crate::progress::bar;

/// Runs `gantry render`.
pub fn run(job: RenderJob) -> Result<()> {
    let tiles = bar(0, "{bar:40} {pos}/{len} tiles, ETA {eta}");
    let report = job.run(Some(Arc::new(move |done, total| {
        tiles.set_length(total as u64);
        tiles.set_position(done as u64);
        if done == total {
            tiles.finish_and_clear();
        }
    })))?;
    println!("{report}");
    Ok(())
}
