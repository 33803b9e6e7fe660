//! Where an algorithm runs: the three executions every record names. Below `algorithms`,
//! `model` and `record` (which name executions but never run them) so every import points
//! down; re-exported as `algorithms::Backend`.

use crate::error::unknown_name;

/// Where an algorithm runs. Written in files (a record's `backend` in `results.json` and
/// `run.json`) as its [`Backend::name`]; a name that is none of them does not read (the error
/// is [`Backend::parse`]'s). Ordered as [`Backend::ALL`], the order reports list executions in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Backend {
    /// The algorithm's kernels on the host, uninstrumented: honest host wall-clock time.
    CpuNative,
    /// The same kernels on the modelled many-core SIMD machine, counting and timing its work.
    CpuModel,
    /// Real GPU passes through wgpu.
    Wgpu,
}

impl Backend {
    pub const ALL: [Backend; 3] = [Backend::CpuNative, Backend::CpuModel, Backend::Wgpu];

    pub fn name(self) -> &'static str {
        match self {
            Backend::CpuNative => "cpu-native",
            Backend::CpuModel => "cpu-model",
            Backend::Wgpu => "wgpu",
        }
    }

    pub fn parse(s: &str) -> std::result::Result<Backend, String> {
        Backend::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| unknown_name("backend", s, &Backend::ALL.map(|b| b.name())))
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // `pad`: a width or alignment (`{:<10}` in progress lines and tables) applies.
        f.pad(self.name())
    }
}

impl serde::Serialize for Backend {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Backend {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Backend, D::Error> {
        struct Name;
        impl serde::de::Visitor<'_> for Name {
            type Value = Backend;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("the name of an execution (cpu-native, cpu-model or wgpu)")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> std::result::Result<Backend, E> {
                Backend::parse(s).map_err(E::custom)
            }
        }
        d.deserialize_str(Name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_execution_is_written_and_read_by_its_name_in_the_order_of_all() {
        for b in Backend::ALL {
            let json = serde_json::to_string(&b).unwrap();
            assert_eq!(json, format!("\"{}\"", b.name()));
            assert_eq!(serde_json::from_str::<Backend>(&json).unwrap(), b);
            assert_eq!(Backend::parse(b.name()), Ok(b));
        }
        let mut sorted = Backend::ALL;
        sorted.sort();
        assert_eq!(sorted, Backend::ALL);
        let e = serde_json::from_str::<Backend>("\n \"cpu-modle\"").unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains("unknown backend 'cpu-modle'")
                && e.contains("did you mean 'cpu-model'")
                && e.ends_with("at line 2 column 12"),
            "{e}"
        );
        assert!(serde_json::from_str::<Backend>("3").is_err());
        assert_eq!(format!("[{:<10}]", Backend::Wgpu), "[wgpu      ]");
    }
}
