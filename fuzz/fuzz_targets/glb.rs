#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use meshvet::formats::Format;

fuzz_target!(|data: &[u8]| common::run(Format::Glb, data));
