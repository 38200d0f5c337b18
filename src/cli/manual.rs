//! `nusselt completions SHELL` and `nusselt manpage`: shell completion
//! scripts (`clap_complete`) and roff man pages (`clap_mangen`), generated
//! from the same command definition the parser uses, so they list exactly
//! the flags that exist, with the help texts of [`super::help`].
//!
//! Invariant: `manpage` without `-o` writes only to stdout; with `-o` the
//! pages are staged and renamed together, like every other output set.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Command};
use clap_complete::Shell;

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    shell: Shell,
}

#[derive(Args, Debug)]
pub struct ManpageArgs {
    /// Write nusselt.1 and one page per subcommand (nusselt-solve.1, …)
    /// into this folder instead of printing nusselt.1.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Prints the completion script of `args.shell` for `cmd`.
pub fn completions(args: CompletionsArgs, mut cmd: Command) -> Result<()> {
    // Into memory first: the generator panics on a failed write.
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut cmd, "nusselt", &mut script);
    std::io::stdout().write_all(&script)?;
    Ok(())
}

/// Prints the main man page, or writes every page into a folder.
pub fn manpage(args: ManpageArgs, cmd: Command) -> Result<()> {
    let cmd = cmd.version(env!("CARGO_PKG_VERSION"));
    let Some(dir) = args.output else {
        let mut page = Vec::new();
        clap_mangen::Man::new(cmd).render(&mut page)?;
        std::io::stdout().write_all(&page)?;
        return Ok(());
    };
    nusselt::output::check_folder(&dir)?;
    let mut set = nusselt::output::OutputSet::create(&dir)?;
    let mut page = Vec::new();
    clap_mangen::Man::new(cmd.clone()).render(&mut page)?;
    set.stage("nusselt.1", &page)?;
    for sub in cmd.get_subcommands() {
        let name: &'static str = format!("nusselt-{}", sub.get_name()).leak();
        let mut page = Vec::new();
        clap_mangen::Man::new(sub.clone().name(name).version(env!("CARGO_PKG_VERSION")))
            .render(&mut page)?;
        set.stage(&format!("{name}.1"), &page)?;
    }
    set.commit()?;
    Ok(())
}
