#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use meshvet::formats::Format;

// The input is the whole `.3mf` package: ZIP directory, inflation, relationships and model XML.
fuzz_target!(|data: &[u8]| common::run(Format::ThreeMf, data));
