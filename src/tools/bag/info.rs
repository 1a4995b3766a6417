//! `rover bag info`: what a bag holds, from its metadata (size, duration, the messages of each
//! topic); a storage file that its recorder never ended is named as such.

use std::path::PathBuf;

use rover_bag::BagReader;

use super::summary;

/// Options of `rover bag info`.
#[derive(Debug, Clone, clap::Args)]
pub struct InfoArgs {
    /// The bag folder (with metadata.yaml).
    #[arg(value_name = "DIR")]
    pub bag: PathBuf,
}

/// The text `rover bag info` prints: the bag's summary, then a line per unfinished storage file.
pub fn info(args: &InfoArgs) -> anyhow::Result<String> {
    let bag = BagReader::open(&args.bag)?;
    let mut text = summary(&args.bag, bag.metadata());
    for file in bag.unfinished_files()? {
        text.push_str(&format!(
            "unfinished: {} was never ended (an interrupted recording); the counts above are those of its last \
             checkpoint\n",
            file.display()
        ));
    }
    Ok(text)
}
