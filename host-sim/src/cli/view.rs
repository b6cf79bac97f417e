//! `host-sim view`: the live 3-D view of a board for Foxglove (the `scene` channels on the
//! Foxglove SDK's WebSocket server, optionally recorded to MCAP), read-only.

use crate::cli::KeyArgs;
use crate::error::CliError;
use clap::Args;
use kinematics_core::guards::Limits;
use kinematics_core::Branch;
use operator::Board;
use robot_config::selection::SelectedRobot;
use robot_description::{to_urdf, Description};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// `host-sim view` options.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// The board: a Unix socket (`host-sim board`, the emulator) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// Where Foxglove connects (WebSocket, subprotocol foxglove.sdk.v1): a port on
    /// 127.0.0.1 (this machine only; 0 picks a free one), or ADDR:PORT.
    #[arg(long, default_value = "8765")]
    pub listen: String,
    /// Also record the channels to this MCAP file.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Stop after this many seconds [default: until Ctrl-C].
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    #[command(flatten)]
    pub key: KeyArgs,
}

/// A scene served live: the server, the optional recording, the channels.
pub(crate) struct LiveScene {
    /// The context the channels and sinks belong to (dropping it ends them).
    _ctx: std::sync::Arc<foxglove::Context>,
    server: foxglove::WebSocketServerHandle,
    mcap: Option<foxglove::McapWriterHandle<std::io::BufWriter<std::fs::File>>>,
    /// The scene's channels.
    pub scene: scene::Scene,
    /// Where Foxglove connects: ws://HOST:PORT.
    pub url: String,
}

impl LiveScene {
    /// Stops the server and closes the recording.
    pub fn close(self) -> Result<(), CliError> {
        self.server.stop().wait_blocking();
        if let Some(w) = self.mcap {
            w.close()
                .map_err(|e| CliError::View(format!("the recording: {e}")))?;
        }
        Ok(())
    }
}

/// The scene of the selected robot on a Foxglove WebSocket server at `listen` (a port on
/// 127.0.0.1, or ADDR:PORT), also recorded to `record` when given.
pub(crate) fn start_scene(
    listen: &str,
    record: Option<&std::path::Path>,
    selected: &SelectedRobot,
    limits: &Limits<f64>,
) -> Result<LiveScene, CliError> {
    let bad = || CliError::View(format!("--listen {listen}: not PORT or ADDR:PORT"));
    let (host, port) = match listen.parse::<u16>() {
        Ok(port) => ("127.0.0.1".to_string(), port),
        Err(_) => match listen.rsplit_once(':') {
            Some((h, p)) => (h.to_string(), p.parse::<u16>().map_err(|_| bad())?),
            None => return Err(bad()),
        },
    };
    let description = Description::new(&selected.robot, limits, Branch::OUTER)
        .map_err(|e| CliError::View(e.to_string()))?;
    let urdf = to_urdf(description.tree(), &selected.source);
    let ctx = foxglove::Context::new();
    let server = ctx
        .websocket_server()
        .name("rspr host-sim")
        .bind(host.clone(), port)
        .start_blocking()
        .map_err(|e| CliError::View(format!("WebSocket server on {host}:{port}: {e}")))?;
    let mcap = match record {
        Some(path) => Some(
            ctx.mcap_writer()
                .create_new_buffered_file(path)
                .map_err(|e| CliError::View(format!("{}: {e}", path.display())))?,
        ),
        None => None,
    };
    let url = format!("ws://{host}:{}", server.port());
    let scene = scene::Scene::new(&ctx, description, urdf);
    Ok(LiveScene {
        _ctx: ctx,
        server,
        mcap,
        scene,
        url,
    })
}

/// Runs `view`.
pub fn run(
    args: &ViewArgs,
    selected: &SelectedRobot,
    limits: &Limits<f64>,
) -> Result<(), CliError> {
    let mut live = start_scene(&args.listen, args.record.as_deref(), selected, limits)?;
    let shutdown = super::board_session::shutdown_on_signals()?;
    super::board_session::stop_after(&shutdown, args.duration_s);
    let mut board = Board::open_with_key(
        &args.connect,
        args.baud,
        Duration::from_secs(10),
        args.key.key()?,
    )?;
    println!(
        "Foxglove WebSocket on {} for the board {} (read-only; topics: {})",
        live.url,
        args.connect.display(),
        scene::TOPICS.join(" ")
    );
    let _ = std::io::stdout().flush();
    let scene = &mut live.scene;
    let counters = super::board_session::with_board(&mut board, &shutdown, |board| {
        Ok(operator::view::run(
            board,
            scene,
            shutdown.flag(),
            &mut |m| println!("view: {m}"),
        )?)
    })?;
    live.close()?;
    println!(
        "view: statuses {}, without a pose for the description {}",
        counters.statuses, counters.unposed
    );
    Ok(())
}
