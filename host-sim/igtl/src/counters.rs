//! What a server has received, refused and sent.

use crate::stream::MalformedKind;
use std::collections::BTreeMap;

/// Most distinct type names counted one by one; further names are counted under
/// [`Counters::OTHER_TYPES`], so that a client cycling through names cannot grow the maps.
pub const MAX_TYPE_NAMES: usize = 64;

/// The server's counters, over all connections since it was bound.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Well-formed messages received, by type name (unknown types included).
    pub received: BTreeMap<String, u64>,
    /// Bad input, by kind (see [`crate::stream`] for what each kind is).
    pub malformed: BTreeMap<MalformedKind, u64>,
    /// Target poses the robot took.
    pub targets_accepted: u64,
    /// Target poses the robot refused (each answered with a STATUS).
    pub targets_refused: u64,
    /// Messages sent, by type name.
    pub sent: BTreeMap<String, u64>,
    /// Streamed pose messages not sent because the client was not reading.
    pub stream_dropped: u64,
    /// Messages that could not be encoded (not expected: names and texts are checked or
    /// cut to size before; counted rather than hidden).
    pub send_failures: u64,
    /// Bytes dropped while resynchronising or skipping oversized bodies.
    pub discarded_bytes: u64,
    /// Connections accepted.
    pub connections_accepted: u64,
    /// Connections refused because the server was full.
    pub connections_refused: u64,
    /// Connections closed (by either side).
    pub connections_closed: u64,
}

/// `TYPE n, TYPE n` of a map, or `none`.
fn by_name<'a>(entries: impl Iterator<Item = (&'a str, u64)>) -> String {
    let parts: Vec<String> = entries.map(|(k, n)| format!("{k} {n}")).collect();
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(", ")
    }
}

/// The counters in words on one line, for a person (the bridge's summary on quitting).
impl std::fmt::Display for Counters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "received {} ({}); sent {} ({}); malformed {} ({}); targets taken {}, refused on arrival {}; \
             poses not streamed to a client not reading {}; send failures {}; bytes discarded {}; \
             connections accepted {}, refused {}, closed {}",
            self.received.values().sum::<u64>(),
            by_name(self.received.iter().map(|(k, n)| (k.as_str(), *n))),
            self.sent.values().sum::<u64>(),
            by_name(self.sent.iter().map(|(k, n)| (k.as_str(), *n))),
            self.malformed.values().sum::<u64>(),
            by_name(self.malformed.iter().map(|(k, n)| (k.name(), *n))),
            self.targets_accepted,
            self.targets_refused,
            self.stream_dropped,
            self.send_failures,
            self.discarded_bytes,
            self.connections_accepted,
            self.connections_refused,
            self.connections_closed,
        )
    }
}

impl Counters {
    /// The key under which type names beyond [`MAX_TYPE_NAMES`] are counted.
    pub const OTHER_TYPES: &'static str = "(other)";

    fn bump(map: &mut BTreeMap<String, u64>, type_name: &str) {
        if let Some(n) = map.get_mut(type_name) {
            *n += 1;
        } else if map.len() < MAX_TYPE_NAMES {
            map.insert(type_name.to_owned(), 1);
        } else {
            *map.entry(Counters::OTHER_TYPES.to_owned()).or_insert(0) += 1;
        }
    }

    pub(crate) fn count_received(&mut self, type_name: &str) {
        Counters::bump(&mut self.received, type_name);
    }

    pub(crate) fn count_sent(&mut self, type_name: &str) {
        Counters::bump(&mut self.sent, type_name);
    }

    pub(crate) fn count_malformed(&mut self, kind: MalformedKind) {
        *self.malformed.entry(kind).or_insert(0) += 1;
    }

    /// Messages received of one type.
    pub fn received_of(&self, type_name: &str) -> u64 {
        self.received.get(type_name).copied().unwrap_or(0)
    }

    /// Messages sent of one type.
    pub fn sent_of(&self, type_name: &str) -> u64 {
        self.sent.get(type_name).copied().unwrap_or(0)
    }

    /// Bad input of one kind.
    pub fn malformed_of(&self, kind: MalformedKind) -> u64 {
        self.malformed.get(&kind).copied().unwrap_or(0)
    }

    /// The counters as one line of JSON (the answer to `GET_STRING` for the counters
    /// device). Type names are printable ASCII without quotes or backslashes escaped.
    pub fn to_json(&self) -> String {
        fn map<'a>(entries: impl Iterator<Item = (&'a str, u64)>) -> String {
            let items: Vec<String> = entries
                .map(|(k, v)| format!("\"{}\":{v}", escape(k)))
                .collect();
            format!("{{{}}}", items.join(","))
        }
        let received = map(self.received.iter().map(|(k, v)| (k.as_str(), *v)));
        let sent = map(self.sent.iter().map(|(k, v)| (k.as_str(), *v)));
        let malformed = map(MalformedKind::ALL
            .iter()
            .map(|k| (k.name(), self.malformed_of(*k))));
        format!(
            "{{\"received\":{received},\"malformed\":{malformed},\"targets_accepted\":{},\"targets_refused\":{},\"sent\":{sent},\"stream_dropped\":{},\"send_failures\":{},\"discarded_bytes\":{},\"connections_accepted\":{},\"connections_refused\":{},\"connections_closed\":{}}}",
            self.targets_accepted,
            self.targets_refused,
            self.stream_dropped,
            self.send_failures,
            self.discarded_bytes,
            self.connections_accepted,
            self.connections_refused,
            self.connections_closed,
        )
    }
}

/// JSON string escaping of the characters a type name may hold.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The summary a person reads on quitting names each count in words, with the type
    /// names as received: no `Debug` text (no braces, no field or type names of Rust).
    #[test]
    fn the_summary_is_in_words() {
        let mut c = Counters::default();
        c.count_received("TRANSFORM");
        c.count_received("TRANSFORM");
        c.count_received("STRING");
        c.count_sent("STATUS");
        c.count_malformed(MalformedKind::BadCrc);
        c.targets_accepted = 1;
        c.targets_refused = 1;
        c.connections_accepted = 1;
        let text = c.to_string();
        assert!(
            text.starts_with("received 3 (STRING 1, TRANSFORM 2); sent 1 (STATUS 1); malformed 1 (bad_crc 1); targets taken 1, refused on arrival 1;"),
            "{text}"
        );
        assert!(!text.contains('{') && !text.contains("Counters"), "{text}");
        assert!(Counters::default()
            .to_string()
            .contains("received 0 (none)"));
    }
}
