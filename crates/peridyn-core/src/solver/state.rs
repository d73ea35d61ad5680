//! A simulation's state as named arrays: what a checkpoint holds so that the run continues
//! bit for bit (everything derived from the scene is rebuilt instead). Encoded little endian:
//! a section count, then per section its name, kind, length and values.

/// One named array.
#[derive(Debug, Clone, PartialEq)]
pub enum Section {
    F64(Vec<f64>),
    U64(Vec<u64>),
    U8(Vec<u8>),
}

impl Section {
    fn kind(&self) -> (u8, &'static str) {
        match self {
            Section::F64(_) => (0, "f64"),
            Section::U64(_) => (1, "u64"),
            Section::U8(_) => (2, "u8"),
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct State {
    sections: Vec<(String, Section)>,
}

/// Reads little-endian values off a byte slice, with the reason when it runs out.
struct Cursor<'a> {
    bytes: &'a [u8],
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.bytes.len() < n {
            return Err(format!(
                "the state ends early ({} bytes left, {n} needed)",
                self.bytes.len()
            ));
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or_default(),
        ))
    }

    /// A length that must fit in what is left, `width` bytes per item.
    fn len(&mut self, width: usize) -> Result<usize, String> {
        let n = self.u64()?;
        if n.saturating_mul(width as u64) > self.bytes.len() as u64 {
            return Err(format!("a section claims {n} values; the state is shorter"));
        }
        Ok(n as usize)
    }
}

impl State {
    pub fn put(&mut self, name: &str, section: Section) {
        self.sections.retain(|(n, _)| n != name);
        self.sections.push((name.to_string(), section));
    }

    pub fn put_f64(&mut self, name: &str, values: Vec<f64>) {
        self.put(name, Section::F64(values));
    }

    pub fn put_u64(&mut self, name: &str, values: Vec<u64>) {
        self.put(name, Section::U64(values));
    }

    pub fn put_u8(&mut self, name: &str, values: Vec<u8>) {
        self.put(name, Section::U8(values));
    }

    fn get(&self, name: &str) -> Result<&Section, String> {
        self.sections
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| s)
            .ok_or_else(|| format!("the state has no `{name}`"))
    }

    /// Section `name` as f64 values, exactly `len` of them.
    pub fn f64(&self, name: &str, len: usize) -> Result<&[f64], String> {
        match self.get(name)? {
            Section::F64(v) => check_len(name, v, len),
            other => Err(wrong_kind(name, other, "f64")),
        }
    }

    pub fn u64(&self, name: &str, len: usize) -> Result<&[u64], String> {
        match self.get(name)? {
            Section::U64(v) => check_len(name, v, len),
            other => Err(wrong_kind(name, other, "u64")),
        }
    }

    pub fn u8(&self, name: &str, len: usize) -> Result<&[u8], String> {
        match self.get(name)? {
            Section::U8(v) => check_len(name, v, len),
            other => Err(wrong_kind(name, other, "u8")),
        }
    }

    pub fn has(&self, name: &str) -> bool {
        self.sections.iter().any(|(n, _)| n == name)
    }

    /// A log of events, each a list of indices (the splits or refinements a checkpoint
    /// replays), as section `name`: every event's length, then its entries; its total length
    /// in `name_len`.
    pub fn put_log<'a>(&mut self, name: &str, events: impl Iterator<Item = &'a [u32]>) {
        let log: Vec<u64> = events
            .flat_map(|e| std::iter::once(e.len() as u64).chain(e.iter().map(|&k| u64::from(k))))
            .collect();
        self.put_u64(&format!("{name}_len"), vec![log.len() as u64]);
        self.put_u64(name, log);
    }

    /// The events of a log written by [`Self::put_log`], each non-empty and within the log
    /// (`what` names an event's entries in the error: "parents", "cells").
    pub fn log(&self, name: &str, what: &str) -> Result<Vec<Vec<u32>>, String> {
        let len = self.u64(&format!("{name}_len"), 1)?[0] as usize;
        let log = self.u64(name, len)?;
        let mut events = Vec::new();
        let mut at = 0;
        while at < log.len() {
            let count = log[at] as usize;
            let end = (at + 1)
                .checked_add(count)
                .filter(|&e| count > 0 && e <= log.len());
            let Some(end) = end else {
                return Err(format!(
                    "`{name}` holds an event of {count} {what} where {} values are left",
                    log.len() - at - 1
                ));
            };
            let entries = log[at + 1..end].iter();
            events.push(
                entries
                    .map(|&k| u32::try_from(k).unwrap_or(u32::MAX))
                    .collect(),
            );
            at = end;
        }
        Ok(events)
    }

    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend((self.sections.len() as u64).to_le_bytes());
        for (name, section) in &self.sections {
            out.extend((name.len() as u64).to_le_bytes());
            out.extend(name.as_bytes());
            out.push(section.kind().0);
            match section {
                Section::F64(v) => {
                    out.extend((v.len() as u64).to_le_bytes());
                    v.iter().for_each(|x| out.extend(x.to_le_bytes()));
                }
                Section::U64(v) => {
                    out.extend((v.len() as u64).to_le_bytes());
                    v.iter().for_each(|x| out.extend(x.to_le_bytes()));
                }
                Section::U8(v) => {
                    out.extend((v.len() as u64).to_le_bytes());
                    out.extend(v);
                }
            }
        }
    }

    pub fn decode(bytes: &[u8]) -> Result<State, String> {
        let mut c = Cursor { bytes };
        let count = c.len(1)?;
        let mut state = State::default();
        for _ in 0..count {
            let name_len = c.len(1)?;
            let name = std::str::from_utf8(c.take(name_len)?)
                .map_err(|_| "a section name is not UTF-8".to_string())?
                .to_string();
            let kind = c.take(1)?[0];
            let section = match kind {
                0 => {
                    let n = c.len(8)?;
                    Section::F64(
                        c.take(8 * n)?
                            .chunks_exact(8)
                            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or_default()))
                            .collect(),
                    )
                }
                1 => {
                    let n = c.len(8)?;
                    Section::U64(
                        c.take(8 * n)?
                            .chunks_exact(8)
                            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
                            .collect(),
                    )
                }
                2 => {
                    let n = c.len(1)?;
                    Section::U8(c.take(n)?.to_vec())
                }
                k => return Err(format!("section `{name}` has an unknown kind {k}")),
            };
            state.sections.push((name, section));
        }
        if !c.bytes.is_empty() {
            return Err(format!("{} bytes after the last section", c.bytes.len()));
        }
        Ok(state)
    }
}

fn check_len<'a, T>(name: &str, v: &'a [T], len: usize) -> Result<&'a [T], String> {
    if v.len() == len {
        Ok(v)
    } else {
        Err(format!(
            "`{name}` holds {} values where this scene has {len}: the checkpoint is of another \
             discretization",
            v.len()
        ))
    }
}

fn wrong_kind(name: &str, found: &Section, wanted: &str) -> String {
    format!("`{name}` holds {} values, not {wanted}", found.kind().1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_what_does_not_fit() {
        let mut s = State::default();
        s.put_f64("position", vec![1.0, -2.5, f64::MIN_POSITIVE]);
        s.put_u64("clock", vec![7, u64::MAX]);
        s.put_u8("intact", vec![1, 0, 1, 1]);
        let mut bytes = Vec::new();
        s.encode(&mut bytes);
        let back = State::decode(&bytes).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.f64("position", 3).unwrap()[1], -2.5);
        assert!(
            back.f64("position", 4)
                .unwrap_err()
                .contains("another discretization")
        );
        assert!(back.u8("position", 3).unwrap_err().contains("not u8"));
        assert!(
            back.u8("velocity", 3)
                .unwrap_err()
                .contains("no `velocity`")
        );
        for cut in [1, 9, bytes.len() / 2, bytes.len() - 1] {
            assert!(State::decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(
            State::decode(&longer)
                .unwrap_err()
                .contains("after the last section")
        );
    }
}
