//! What the settings' checks resolve besides the parsed command line, handed to the commands with
//! it (so that no field of a clap struct is set after parsing).

/// What the settings' checks resolved besides the parsed command line: whether the user stated
/// g (`--g`, `--latitude`: a campaign's `# g_m_s2:` line then does not apply), and what a
/// station's settings file gave.
#[derive(Debug, Default)]
pub struct Resolved {
    /// `--g` or `--latitude` was given.
    pub g_stated: bool,
    /// `station --config`: the file's keys, and those the command line overrode.
    pub config: Option<ConfigUse>,
}

/// What a station's settings file gave, for the station's first line.
#[derive(Debug, Default)]
pub struct ConfigUse {
    /// The file.
    pub path: std::path::PathBuf,
    /// The keys it gave, in the file's order.
    pub keys: Vec<String>,
    /// Its keys the command line overrode.
    pub overridden: Vec<String>,
}
