//! Serves a corpus directory (and optionally a model and trait set) on 127.0.0.1 and prints
//! the address; open it in a browser.
//!
//! `cargo run --release -p serve --example serve_corpus -- CORPUS_DIR [model.bin traits.json]`

use std::sync::Arc;

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let config = serve::Config {
        corpus: args.first().map(Into::into),
        model: args.get(1).map(Into::into),
        traits: args.get(2).map(Into::into).into_iter().collect(),
        bind: "127.0.0.1:0".parse()?,
        ..serve::Config::default()
    };
    let app = Arc::new(serve::App::new(config.clone())?);
    let listener = serve::bind(&config).await?;
    println!("open http://{}/ (ctrl-c to stop)", listener.local_addr()?);
    serve::serve(app, listener).await?;
    Ok(())
}
