//! `painterly preview`: a live view of a painted character in the browser.
//!
//! A loopback web server (axum + tokio) serves one page of our own (plain
//! WebGL2, embedded in the binary) and evaluates frames on demand: the
//! timeline, one slider per configuration axis (pose mode overrides), and
//! the orbit camera as the eye of viewDirection axes and view-dependent
//! meshes. See docs/preview.md for the protocol.
//!
//! | module | concept |
//! |---|---|
//! | [`protocol`] | requests, the binary frame format, the scene description |
//! | [`evaluator`] | the thread that owns the character and evaluates frames |
//! | [`server`] | routes, assets, host check, websocket stream |
//! | [`connections`] | accepting connections: a cap and a header timeout |

pub mod connections;
pub mod evaluator;
pub mod protocol;
pub mod server;

use std::io::Write;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

use crate::error::{Error, Result};

/// `painterly preview` options.
#[derive(Debug, Clone, clap::Args)]
pub struct PreviewArgs {
    /// The painted character (.usda, .usdc or .usdz). Never written.
    pub input: PathBuf,
    /// A layer `painterly bake` wrote from INPUT: the page can show its
    /// frames beside the live evaluation ("show bake").
    #[arg(long, value_name = "LAYER")]
    pub bake: Option<PathBuf>,
    /// Camera prim for viewDirection axes without a source and for every
    /// view-dependent mesh (overrides their painterly:camera), as in bake;
    /// also where the page's orbit starts.
    #[arg(long, value_name = "PRIM")]
    pub camera: Option<String>,
    /// Port to listen on; 0 picks a free one (the URL printed says which).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
    /// Address to listen on. The default serves this machine only; any
    /// other address lets other machines evaluate (never write) the input.
    /// `localhost` is 127.0.0.1; `0.0.0.0` serves every address.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST), value_name = "ADDR", value_parser = parse_host)]
    pub host: IpAddr,
}

/// `--host`: an IP address, or `localhost` (no name lookup: the address
/// served is the one given).
fn parse_host(s: &str) -> std::result::Result<IpAddr, String> {
    if s.eq_ignore_ascii_case("localhost") {
        return Ok(IpAddr::V4(Ipv4Addr::LOCALHOST));
    }
    s.parse::<IpAddr>()
        .map_err(|_| format!("{s:?} is not an IP address (or localhost)"))
}

/// The URL to print for `local`: an unspecified address (0.0.0.0, ::) is
/// not one a browser can open, so this machine's loopback stands for it.
fn page_url(local: SocketAddr) -> String {
    let shown = match local.ip() {
        IpAddr::V4(ip) if ip.is_unspecified() => SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), local.port()),
        IpAddr::V6(ip) if ip.is_unspecified() => {
            SocketAddr::new(IpAddr::V6(std::net::Ipv6Addr::LOCALHOST), local.port())
        }
        _ => local,
    };
    format!("http://{shown}/")
}

/// Opens the character, binds, prints the URL and serves until killed.
pub fn run(args: &PreviewArgs) -> Result<()> {
    crate::usd_io::stage::require_file(&args.input, "input")?;
    let evaluator = evaluator::Evaluator::start(&args.input, args.camera.as_deref(), args.bake.as_deref())?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| Error::msg(format!("cannot start the server runtime: {e}")))?;
    runtime.block_on(async move {
        let addr = SocketAddr::new(args.host, args.port);
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| Error::msg(format!("cannot listen on {addr}: {e}")))?;
        let local = listener
            .local_addr()
            .map_err(|e| Error::msg(format!("cannot read the listening address: {e}")))?;
        let state = Arc::new(server::AppState {
            evaluator,
            hosts: allowed_hosts(local),
        });
        let url = page_url(local);
        println!("painterly preview of {}: {url}", args.input.display());
        if local.ip().is_unspecified() {
            println!("(serving every address of this machine; Ctrl-C stops)");
        } else {
            println!("(serving {} only; Ctrl-C stops)", local.ip());
        }
        let _ = std::io::stdout().flush();
        connections::serve(listener, server::router(state)).await;
        Ok(())
    })
}

/// `Host` header values a browser sends for this server on loopback;
/// `None` (any host) when serving another address on purpose (`--host`).
pub fn allowed_hosts(local: SocketAddr) -> Option<Vec<String>> {
    if !local.ip().is_loopback() {
        return None;
    }
    let port = local.port();
    let mut hosts = vec![
        local.to_string(),
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        format!("[::1]:{port}"),
    ];
    hosts.dedup();
    Some(hosts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_url_printed_is_the_address_served_or_the_loopback_for_every_address() {
        let url = |a: &str| page_url(a.parse().unwrap());
        assert_eq!(url("192.168.1.7:8765"), "http://192.168.1.7:8765/");
        assert_eq!(url("0.0.0.0:8765"), "http://127.0.0.1:8765/");
        assert_eq!(url("[fe80::1]:80"), "http://[fe80::1]:80/");
        assert_eq!(url("[::]:80"), "http://[::1]:80/");
    }

    #[test]
    fn host_is_an_ip_address_or_localhost() {
        assert_eq!(parse_host("LocalHost"), Ok(IpAddr::V4(Ipv4Addr::LOCALHOST)));
        assert_eq!(parse_host("::1"), Ok("::1".parse().unwrap()));
        assert_eq!(
            parse_host("example.com"),
            Err("\"example.com\" is not an IP address (or localhost)".into())
        );
    }
}
