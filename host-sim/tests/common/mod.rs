//! Helpers shared by the integration tests: run the binary, read its CSV.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::process::{Command, Stdio};

/// What one run of the binary produced.
pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

/// Runs `host-sim` with `args`, feeding `stdin`.
pub fn host_sim(args: &[&str], stdin: &str) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn host-sim");
    let mut input = child.stdin.take().expect("stdin");
    let text = stdin.to_string();
    let writer = std::thread::spawn(move || {
        // The binary may exit before reading (e.g. on a flag error); ignore broken pipes.
        let _ = input.write_all(text.as_bytes());
    });
    let out = child.wait_with_output().expect("wait for host-sim");
    writer.join().expect("stdin writer");
    Run {
        code: out.status.code(),
        stdout: String::from_utf8(out.stdout).expect("utf-8 stdout"),
        stderr: String::from_utf8(out.stderr).expect("utf-8 stderr"),
    }
}

/// Runs and asserts success.
pub fn ok(args: &[&str], stdin: &str) -> String {
    let r = host_sim(args, stdin);
    assert_eq!(r.code, Some(0), "host-sim {args:?} failed: {}", r.stderr);
    r.stdout
}

/// A parsed CSV table.
pub struct Table {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn parse(text: &str) -> Table {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .from_reader(text.as_bytes());
        let header = reader
            .headers()
            .unwrap()
            .iter()
            .map(str::to_string)
            .collect();
        let rows = reader
            .records()
            .map(|r| r.unwrap().iter().map(str::to_string).collect())
            .collect();
        Table { header, rows }
    }

    /// Index of a column; panics naming it if absent or repeated.
    pub fn col(&self, name: &str) -> usize {
        let hits: Vec<usize> = (0..self.header.len())
            .filter(|&i| self.header[i] == name)
            .collect();
        assert_eq!(hits.len(), 1, "column {name} in {:?}", self.header);
        hits[0]
    }

    pub fn text(&self, row: usize, name: &str) -> &str {
        &self.rows[row][self.col(name)]
    }

    pub fn num(&self, row: usize, name: &str) -> f64 {
        let t = self.text(row, name);
        t.parse()
            .unwrap_or_else(|_| panic!("row {row} {name}: {t:?} is not a number"))
    }
}

// The column names are the library's own (one source of truth).
#[allow(unused_imports)] // not every test binary uses every name
pub use robot_config::edge::{POSE, RSPR_JOINTS, USR_JOINTS};

/// A pose table: header then `x,y,z,rx,ry,rz,branch` rows.
pub fn pose_csv(rows: &[([f64; 6], u32)]) -> String {
    let mut s = String::from("x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n");
    for (p, b) in rows {
        let f: Vec<String> = p.iter().map(|v| format!("{v:.12}")).collect();
        s.push_str(&format!("{},{b}\n", f.join(",")));
    }
    s
}

/// The path of a shipped geometry file.
pub fn geometry(name: &str) -> String {
    format!(
        "{}/robot-config/geometry/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}
