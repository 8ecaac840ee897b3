//! Fuzz target: any text as a scene file (parse and validate). Any panic is
//! a bug: bad scenes must come back as `RecipeError`s.

#![no_main]

use lapidary::scene::parse_scene;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_scene(text, None);
});
