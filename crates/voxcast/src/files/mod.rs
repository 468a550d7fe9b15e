//! The file system rules every command follows: inputs are opened only as
//! regular files, with their sizes known before anything is read
//! ([`input`]); outputs are checked against the inputs and written all
//! together or not at all ([`output`]).

pub mod input;
pub mod output;

pub use input::{
    open, read_bytes, read_own_toml, read_text, read_toml, record_inputs, regular_file, was_read,
    MAX_TEXT_BYTES,
};
pub use output::{check_folder, write_file, writes_into_input, Outputs};
