//! Master-slave teleoperation with a hand controller: a [`Master`] device through the
//! teleoperation mapping ([`masters::Teleop`]: scaling, clutch, dead-man, tremor filter,
//! limits) to the board, at the stream rate, with the board's status as the operator's
//! cue, every sample, target, status and event recorded (MCAP), and the latency measured.
//!
//! # What goes to the board
//!
//! - Following: each tick's `servo_cp` as a `PoseTarget` (stamped with the link's clock).
//! - The master's buttons, when they change: the clutch as `Clutch { engaged }` (engaged:
//!   the master is decoupled and the robot holds) and the dead-man as
//!   `OperatorPresent { present }` (released: the robot holds). The mapping holds on its
//!   side at the same tick, so the board never sees a target while it is told to hold.
//! - Heartbeats, every 20 ms ([`Board::poll`]).
//!
//! # Re-engaging without a jump
//!
//! The board stops under power when told to hold (SS2), a little short of the last target
//! the mapping sent. So while the mapping holds, every status re-anchors it at the board's
//! setpoint (`Teleop::resync`): on re-engaging, the robot's reference is where the board
//! stands, the master's offset is captured there, and the first target equals it.

use crate::board::{request_name, Board, BoardError, BoardEvent, Outcome, Reply};
use crate::conversions::{margins, measured_cp, setpoint_cp};
use crate::error::OperatorError;
use master_link::{MasterToBoard, NackReason, RobotState, StatusReport};
use masters::latency::{LagConfig, LatencyFigures};
use masters::recording::{
    latency_of, EventKind, EventRecord, InputRecord, RecordingWriter, SessionInfo, StatusRecord,
    TargetRecord,
};
use masters::{
    CartesianPose, CueLevel, EdgeCue, EdgeCueConfig, Master, MasterSample, OperatorButtons, Teleop,
    TeleopConfig, TeleopOutput, TeleopState,
};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

/// What a teleoperation run does.
#[derive(Clone, Debug, Default)]
pub struct TeleoperationSettings {
    /// The mapping (stream rate, scale, filter, limits, registration).
    pub teleop: TeleopConfig,
    /// The workspace-edge cue's thresholds.
    pub cue: EdgeCueConfig,
    /// Stop after this long, s (None: until the stop flag is set).
    pub duration_s: Option<f64>,
    /// The MCAP file to record to.
    pub record: Option<PathBuf>,
    /// Settings written into the recording's session record (as text).
    pub settings_text: BTreeMap<String, String>,
}

/// Everything a run saw, in memory (the recording holds the same).
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Master samples.
    pub inputs: Vec<InputRecord>,
    /// Targets sent.
    pub targets: Vec<TargetRecord>,
    /// Board statuses.
    pub statuses: Vec<StatusRecord>,
    /// Teleoperation events (state, cue, refusals).
    pub events: Vec<EventRecord>,
    /// The raw statuses with their arrival times.
    pub reports: Vec<(f64, StatusReport)>,
}

/// What one tick shows the operator.
#[derive(Clone, Copy, Debug)]
pub struct TickView<'a> {
    /// The link's clock, s.
    pub t_s: f64,
    /// Following or holding, and why.
    pub state: TeleopState,
    /// The workspace-edge cue.
    pub cue: CueLevel,
    /// The latest status.
    pub status: Option<&'a StatusReport>,
    /// The last target sent.
    pub target: Option<CartesianPose>,
    /// The master's buttons.
    pub buttons: OperatorButtons,
    /// The board's latest refusal of a target: when (the link's clock, s) and why, in
    /// words with the guard, the value and the limit.
    pub refusal: Option<(f64, &'a str)>,
}

/// The figures of a run.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// The master device.
    pub master: String,
    /// What was seen.
    pub trace: Trace,
    /// The mapping's counters.
    pub stats: masters::teleop::TeleopStats,
    /// Targets sent.
    pub targets_sent: u64,
    /// Targets the board refused (at once, or by its path check after the `Ack`), by the
    /// guard or rule that refused them.
    pub targets_refused: BTreeMap<String, u64>,
    /// The first refusal of each guard or rule (keys as in `targets_refused`): when (the
    /// link's clock, s) and its words, with the value and the limit.
    pub first_refusals: BTreeMap<String, (f64, String)>,
    /// Other requests refused: (time, request, reason).
    pub refused: Vec<(f64, &'static str, NackReason)>,
    /// Device read errors.
    pub device_errors: u64,
    /// The tremor filter's group delay at DC, s (None: no filter).
    pub filter_delay_s: Option<f64>,
    /// The latency figures.
    pub latency: LatencyFigures,
    /// The recording written.
    pub recording: Option<PathBuf>,
}

impl RunReport {
    /// The last status received.
    pub fn final_status(&self) -> Option<&StatusReport> {
        self.trace.reports.last().map(|(_, s)| s)
    }

    /// The run's summary with `last` as the board's final status: the status the board
    /// reported after the last command (a `Disable` after the run), when there is one.
    pub fn summary_after(&self, last: Option<&StatusReport>) -> String {
        let summary = self.summary();
        let (Some(last), Some(traced)) = (last, self.final_status()) else {
            return summary;
        };
        summary.replace(&final_line(traced), &final_line(last))
    }

    /// The run's summary as printed by `host-sim teleop --device`.
    pub fn summary(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "--- teleoperation summary ({})", self.master);
        let s = &self.stats;
        let _ = writeln!(
            o,
            "ticks {}: following {} ({} limited by the master's limits), held: clutched {}, operator absent {}, master lost {}, stream gap {}, no master {}; engagements {}",
            s.ticks,
            s.following,
            s.limited,
            s.hold_clutched,
            s.hold_operator_absent,
            s.hold_master_lost,
            s.hold_stream_gap,
            s.hold_no_master,
            s.engagements
        );
        let refused: Vec<String> = self
            .targets_refused
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let _ = writeln!(
            o,
            "targets sent {}, refused {}{}",
            self.targets_sent,
            self.targets_refused.values().sum::<u64>(),
            if refused.is_empty() {
                String::new()
            } else {
                format!(" ({})", refused.join(", "))
            }
        );
        for (kind, (t, words)) in &self.first_refusals {
            let _ = writeln!(o, "  {kind}: the first at {t:.2} s: {words}");
        }
        for (t, what, reason) in &self.refused {
            let _ = writeln!(
                o,
                "  at {t:.2} s the board refused {what}: {}",
                board_words::reason(*reason)
            );
        }
        if self.device_errors > 0 {
            let _ = writeln!(o, "device read errors: {}", self.device_errors);
        }
        if let Some(st) = self.final_status() {
            let _ = writeln!(o, "{}", final_line(st));
        }
        if let Some(d) = self.filter_delay_s {
            let _ = writeln!(
                o,
                "tremor filter: group delay at DC {:.1} ms (part of master input -> target)",
                d * 1e3
            );
        }
        let _ = writeln!(o, "latency (lag along the path while moving):");
        let _ = write!(o, "{}", self.latency);
        if let Some(p) = &self.recording {
            let _ = writeln!(o, "recording: {}", p.display());
        }
        o
    }
}

fn status_record(t_s: f64, s: &StatusReport) -> StatusRecord {
    let m = margins(s);
    StatusRecord {
        t_s,
        state: board_words::state_label(s.state).to_string(),
        measured: measured_cp(s),
        setpoint: setpoint_cp(s),
        nearest_margin: m.iter().find(|(k, _)| *k == "nearest").map(|(_, v)| *v),
        faults: s.faults.bits(),
        margins: m.into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
        stop: board_words::stop(s.state, s.stop).map(str::to_string),
    }
}

/// The recording and the in-memory trace, written together.
struct Recorder {
    writer: Option<RecordingWriter>,
    trace: Trace,
}

impl Recorder {
    fn input(&mut self, r: InputRecord) -> Result<(), OperatorError> {
        if let Some(w) = &mut self.writer {
            w.write_input(&r)?;
        }
        self.trace.inputs.push(r);
        Ok(())
    }
    fn target(&mut self, r: TargetRecord) -> Result<(), OperatorError> {
        if let Some(w) = &mut self.writer {
            w.write_target(&r)?;
        }
        self.trace.targets.push(r);
        Ok(())
    }
    fn status(&mut self, t_s: f64, s: &StatusReport) -> Result<(), OperatorError> {
        let r = status_record(t_s, s);
        if let Some(w) = &mut self.writer {
            w.write_status(&r)?;
        }
        self.trace.statuses.push(r);
        self.trace.reports.push((t_s, *s));
        Ok(())
    }
    fn event(&mut self, r: EventRecord) -> Result<(), OperatorError> {
        if let Some(w) = &mut self.writer {
            w.write_event(&r)?;
        }
        self.trace.events.push(r);
        Ok(())
    }
    fn note(&mut self, t_s: f64, detail: String) -> Result<(), OperatorError> {
        self.event(EventRecord {
            t_s,
            kind: EventKind::Note,
            detail,
        })
    }
}

/// Runs teleoperation with `master` on an enabled `board` until `settings.duration_s`
/// or `stop`; `observe` sees every tick (a live display). The board stays enabled and
/// holding at the end (the caller disables it).
pub fn run(
    board: &mut Board,
    master: &mut dyn Master,
    settings: &TeleoperationSettings,
    stop: &AtomicBool,
    observe: &mut dyn FnMut(&TickView),
) -> Result<RunReport, OperatorError> {
    // Events older than the run are not part of it.
    board.discard_events();
    let status = enabled_status(board)?;
    let start_pose = setpoint_cp(&status)
        .or_else(|| measured_cp(&status))
        .ok_or(BoardError::NoStatus)?;
    let mut teleop = Teleop::new(settings.teleop.clone())?;
    let cue = EdgeCue::new(settings.cue)?;
    let period_s = 1.0 / settings.teleop.stream_rate_hz;
    let t_start = board.now_s();
    teleop.start(t_start, start_pose)?;
    let writer = match &settings.record {
        Some(path) => Some(create_recording(path, board, master, settings, t_start)?),
        None => None,
    };
    let mut state = RunState::new(teleop, cue, writer, master.name(), status);
    state
        .rec
        .event(EventRecord::scale(t_start, settings.teleop.scale))?;
    let mut next = t_start;
    let mut last_t = t_start;
    loop {
        if stop.load(Ordering::Relaxed)
            || settings
                .duration_s
                .is_some_and(|d| board.now_s() - t_start >= d)
        {
            break;
        }
        for e in board.poll_until(next)? {
            match e {
                BoardEvent::Status(t, s) => state.status(t, &s)?,
                BoardEvent::Reply(r) => state.reply(&r)?,
                BoardEvent::TargetRefused(t, r) => state.target_refused(t, &r)?,
            }
        }
        let t = board.now_s();
        next += period_s;
        if next < t - period_s {
            // Late by more than a period (a stalled host): do not pile ticks up.
            next = t + period_s;
        }
        if t <= last_t {
            continue;
        }
        last_t = t;
        state.tick(board, master, t)?;
        observe(&state.view(t));
    }
    state.finish()
}

/// The board's status, which must say `Enabled`: the latest, or the next within 1 s.
fn enabled_status(board: &mut Board) -> Result<StatusReport, OperatorError> {
    let status = match board.status() {
        Some((_, s)) => *s,
        None => board
            .wait_status(1.0, |_| true)?
            .ok_or(BoardError::NoStatus)?,
    };
    if status.state != RobotState::Enabled {
        return Err(BoardError::NotEnabled {
            state: board_words::state(status.state).to_string(),
        }
        .into());
    }
    Ok(status)
}

/// Creates the recording at `path` (and its directory), its session record carrying the
/// settings of the run that starts at `t_start` on the link's clock.
fn create_recording(
    path: &std::path::Path,
    board: &Board,
    master: &dyn Master,
    settings: &TeleoperationSettings,
    t_start: f64,
) -> Result<RecordingWriter, OperatorError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| OperatorError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let unix_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let start_unix_ns = unix_ns.saturating_sub((t_start * 1e9) as u64);
    let mut text = settings.settings_text.clone();
    text.insert("board".into(), board.name().into());
    let s = &settings.teleop.scale;
    text.insert("scale_translation".into(), s.translation.to_string());
    text.insert("scale_rotation".into(), s.rotation.to_string());
    text.insert(
        "tremor_filter".into(),
        format!("{:?}", settings.teleop.tremor),
    );
    text.insert("limits".into(), format!("{:?}", settings.teleop.limits));
    Ok(RecordingWriter::create(
        path,
        &SessionInfo {
            start_unix_ns,
            master: master.name().into(),
            stream_rate_hz: settings.teleop.stream_rate_hz,
            settings: text,
        },
    )?)
}

/// A run in progress: the mapping, the cue, what was recorded and counted, and what the
/// operator was last shown.
struct RunState {
    teleop: Teleop,
    cue: EdgeCue,
    rec: Recorder,
    report: RunReport,
    last_state: TeleopState,
    /// The buttons as last told to the board (None: not yet).
    buttons_sent: Option<OperatorButtons>,
    buttons: OperatorButtons,
    last_sample_t: Option<f64>,
    last_target: Option<CartesianPose>,
    latest_status: StatusReport,
    /// The latest refusal of a target: when and its words.
    last_refusal: Option<(f64, String)>,
}

impl RunState {
    fn new(
        teleop: Teleop,
        cue: EdgeCue,
        writer: Option<RecordingWriter>,
        master: &str,
        status: StatusReport,
    ) -> Self {
        let report = RunReport {
            master: master.into(),
            trace: Trace::default(),
            stats: teleop.stats(),
            targets_sent: 0,
            targets_refused: BTreeMap::new(),
            first_refusals: BTreeMap::new(),
            refused: Vec::new(),
            device_errors: 0,
            filter_delay_s: teleop.filter().map(|f| f.dc_group_delay_s()),
            latency: LatencyFigures::default(),
            recording: None,
        };
        RunState {
            last_state: teleop.state(),
            teleop,
            cue,
            rec: Recorder {
                writer,
                trace: Trace::default(),
            },
            report,
            buttons_sent: None,
            buttons: OperatorButtons::default(),
            last_sample_t: None,
            last_target: None,
            latest_status: status,
            last_refusal: None,
        }
    }

    /// A status: recorded, the workspace-edge cue updated, and while the mapping holds,
    /// its reference re-anchored at the board's setpoint.
    fn status(&mut self, t: f64, s: &StatusReport) -> Result<(), OperatorError> {
        self.rec.status(t, s)?;
        self.latest_status = *s;
        let m = f64::from(s.margins.nearest);
        if m.is_finite() {
            // A margin beyond the stop level is at the edge; above 1, far.
            let before = self.cue.level();
            let level = self.cue.update(m.clamp(0.0, 1.0))?;
            if level != before {
                self.rec.event(EventRecord::cue(t, level))?;
            }
        }
        // Holding: the robot's reference is where the board stands.
        if matches!(self.teleop.state(), TeleopState::Holding(_)) && s.state == RobotState::Enabled
        {
            if let Some(p) = setpoint_cp(s) {
                self.teleop.resync(p)?;
            }
        }
        Ok(())
    }

    /// The answer to a request: targets refused counted by reason, other refusals and
    /// unanswered requests noted.
    fn reply(&mut self, r: &Reply) -> Result<(), OperatorError> {
        match (r.request, r.outcome) {
            (MasterToBoard::PoseTarget { .. }, Outcome::Refused(reason)) => {
                let words = board_words::reason(reason).to_string();
                self.count_refusal(r.t_s, words.clone(), words);
            }
            (MasterToBoard::PoseTarget { .. }, Outcome::TargetRefused(refused)) => {
                let words = board_words::refusal(&refused);
                self.count_refusal(r.t_s, refusal_kind(&refused), words.clone());
                self.rec
                    .note(r.t_s, format!("target refused at once: {words}"))?;
            }
            (MasterToBoard::PoseTarget { .. }, _) => {}
            (req, Outcome::Refused(reason)) => {
                let what = request_name(&req);
                self.report.refused.push((r.t_s, what, reason));
                self.rec.note(
                    r.t_s,
                    format!("refused {what}: {}", board_words::reason(reason)),
                )?;
            }
            (req, Outcome::NoReply) => {
                self.rec
                    .note(r.t_s, format!("no answer to {}", request_name(&req)))?;
            }
            _ => {}
        }
        Ok(())
    }

    /// A target the board's path check refused after its acknowledgement: counted with
    /// the targets refused and noted in the recording in words.
    fn target_refused(
        &mut self,
        t: f64,
        refused: &master_link::RefusedTarget,
    ) -> Result<(), OperatorError> {
        self.count_refusal(t, refusal_kind(refused), board_words::refusal(refused));
        self.rec.note(
            t,
            format!(
                "target refused by the board's path check: {}",
                board_words::refusal(refused)
            ),
        )
    }

    /// A refused target of `kind` (the guard or rule) at `t`, in `words`: counted, the
    /// first of its kind kept for the summary, the latest for the live view.
    fn count_refusal(&mut self, t: f64, kind: String, words: String) {
        self.report
            .first_refusals
            .entry(kind.clone())
            .or_insert_with(|| (t, words.clone()));
        *self.report.targets_refused.entry(kind).or_default() += 1;
        self.last_refusal = Some((t, words));
    }

    /// One tick at `t`: the master's sample, its buttons told to the board when they
    /// change, the mapping's step and the target it streams.
    fn tick(
        &mut self,
        board: &mut Board,
        master: &mut dyn Master,
        t: f64,
    ) -> Result<(), OperatorError> {
        let sample = self.sample(master, t)?;
        if let Some(s) = &sample {
            self.rec.input(InputRecord::from(s))?;
            self.last_sample_t = Some(s.t_s);
            self.buttons = s.buttons;
            self.send_buttons(board)?;
        }
        let out = self.teleop.step(t, sample.as_ref())?;
        if let TeleopOutput::ServoCp { pose, limited } = out {
            let (_, stamp) = board.send_target(&pose)?;
            self.report.targets_sent += 1;
            self.last_target = Some(pose);
            self.rec.target(TargetRecord {
                t_s: board.now_s(),
                timestamp_us: stamp,
                pose,
                limited,
                input_t_s: self.last_sample_t,
                commanded: self.teleop.commanded(),
            })?;
        }
        if self.teleop.state() != self.last_state {
            self.last_state = self.teleop.state();
            self.rec.event(EventRecord::state(t, self.last_state))?;
        }
        Ok(())
    }

    /// The master's sample at `t`; a read error counts (the first is noted) and gives none.
    fn sample(
        &mut self,
        master: &mut dyn Master,
        t: f64,
    ) -> Result<Option<MasterSample>, OperatorError> {
        match master.poll(t) {
            Ok(s) => Ok(s),
            Err(e) => {
                self.report.device_errors += 1;
                if self.report.device_errors == 1 {
                    self.rec.note(t, format!("device: {e}"))?;
                }
                Ok(None)
            }
        }
    }

    /// Tells the board the dead-man and the clutch, each when it changed.
    fn send_buttons(&mut self, board: &mut Board) -> Result<(), OperatorError> {
        let (before, buttons) = (self.buttons_sent, self.buttons);
        if before.is_none_or(|b| b.operator_present != buttons.operator_present) {
            board.send(MasterToBoard::OperatorPresent {
                present: buttons.operator_present,
            })?;
        }
        if before.is_none_or(|b| b.clutch != buttons.clutch) {
            board.send(MasterToBoard::Clutch {
                engaged: buttons.clutch,
            })?;
        }
        self.buttons_sent = Some(buttons);
        Ok(())
    }

    /// What the operator sees at `t`.
    fn view(&self, t: f64) -> TickView<'_> {
        TickView {
            t_s: t,
            state: self.teleop.state(),
            cue: self.cue.level(),
            status: Some(&self.latest_status),
            target: self.last_target,
            buttons: self.buttons,
            refusal: self
                .last_refusal
                .as_ref()
                .map(|(t, words)| (*t, words.as_str())),
        }
    }

    /// The run's figures: the mapping's counters, the latency, the recording closed.
    fn finish(mut self) -> Result<RunReport, OperatorError> {
        let mut report = self.report;
        report.stats = self.teleop.stats();
        report.latency = latency_of(
            &self.rec.trace.targets,
            &self.rec.trace.statuses,
            &LagConfig::default(),
        );
        report.recording = match self.rec.writer.take() {
            Some(w) => Some(w.finish()?),
            None => None,
        };
        report.trace = self.rec.trace;
        Ok(report)
    }
}

/// The board's final status in words: its state, the stop in force (none when none is),
/// the fault with its cause, joint and value, the targets its supervisor refused and the
/// nearest guard margin with its warn and stop levels.
fn final_line(st: &StatusReport) -> String {
    let stop =
        board_words::stop(st.state, st.stop).map_or(String::new(), |s| format!(", stop: {s}"));
    let fault = board_words::fault(&st.fault).map_or(String::new(), |f| format!(", fault: {f}"));
    format!(
        "board: final state {}{stop}{fault}; targets refused by the supervisor {}; margins {}",
        board_words::state(st.state),
        st.targets_refused,
        board_words::nearest_margin(&st.margins)
    )
}

/// The kind of a refused target, for counting: the guard or rule that refused it.
fn refusal_kind(r: &master_link::RefusedTarget) -> String {
    match r.breach.guard {
        master_link::GuardId::None => board_words::reason(r.reason).to_string(),
        g => board_words::guard_name(g).to_string(),
    }
}
