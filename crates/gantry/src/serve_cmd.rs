//! `gantry serve`: the material viewer and editor in the browser (the `serve` crate).

use anyhow::{Context, Result};
use clap::Args;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

/// Arguments of `gantry serve`.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Corpus: a folder of neural-BRDF weights and/or .binary files, or a corpus store;
    /// default: the shared MERL set.
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// Model file (`gantry model build`), for editing and trait scores.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Trait set JSON (`gantry traits fit`); repeat for several spaces.
    #[arg(long)]
    traits: Vec<PathBuf>,
    /// Where a model built from the corpus is cached, without --model (default: beside the
    /// corpus, `<corpus>.gantry-cache`, or `~/.cache/gantry` where that cannot be written).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Without --model: build the model and the default trait sets from the corpus at start
    /// (otherwise the page offers it; a cached build is always used).
    #[arg(long, conflicts_with = "model")]
    build: bool,
    /// Lat-long light probe (OpenEXR or Radiance .hdr) of the environment view.
    #[arg(long)]
    env: Option<PathBuf>,
    /// Port (0 picks a free one; the address is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Address to bind; anything but a loopback address exposes the editor to the network.
    #[arg(long, default_value = "127.0.0.1")]
    bind: IpAddr,
    /// Largest upload accepted, in MiB.
    #[arg(long, default_value_t = 40)]
    upload_limit_mib: u64,
}

/// Runs the server until ctrl-c.
pub fn run(a: ServeArgs) -> Result<()> {
    let corpus = a.corpus.or_else(|| {
        let d = brdf::data_dir().join("nbrdf/merl");
        d.is_dir().then_some(d)
    });
    let config = serve::Config {
        corpus,
        model: a.model,
        traits: a.traits,
        cache: a.cache,
        environment: a.env,
        upload_limit: a.upload_limit_mib * 1024 * 1024,
        bind: SocketAddr::new(a.bind, a.port),
    };
    if !a.bind.is_loopback() {
        eprintln!(
            "warning: listening on {}: anyone who can reach it can use the editor",
            a.bind
        );
    }
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async move {
        let app = Arc::new(serve::App::new(config.clone()).context("cannot start the server")?);
        let listener = serve::bind(&config).await?;
        let addr = listener.local_addr().context("no local address")?;
        println!("gantry serve: http://{addr}/");
        if a.build {
            let status = app.prepare_editing(true);
            eprintln!("{}", status.message);
        }
        serve::serve(app, listener).await?;
        Ok(())
    })
}
