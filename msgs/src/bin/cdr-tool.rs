//! `cdr-tool`: encode/decode any causal_arm_msgs type between JSON and CDR hex.
//! Used by the golden tests against Python `rosbags`, and handy for debugging bags.

use std::io::Read as _;
use std::process::ExitCode;

const USAGE: &str = "usage: cdr-tool encode TYPE < json | decode TYPE HEX | definition TYPE | list";

fn hex_decode(text: &str) -> Result<Vec<u8>, String> {
    let text = text.trim();
    if !text.is_ascii() {
        return Err("hex input contains non-ASCII characters".to_owned());
    }
    if !text.len().is_multiple_of(2) {
        return Err(format!("hex input has odd length {}", text.len()));
    }
    (0..text.len())
        .step_by(2)
        .map(|i| {
            u8::from_str_radix(&text[i..i + 2], 16)
                .map_err(|_| format!("invalid hex at offset {i}"))
        })
        .collect()
}

fn run(args: &[String]) -> Result<String, String> {
    match args {
        [cmd] if cmd == "list" => Ok(causal_arm_msgs::message_types().join("\n")),
        [cmd, ty] if cmd == "definition" => causal_arm_msgs::definition_of(ty)
            .map(str::to_owned)
            .map_err(|e| e.to_string()),
        [cmd, ty] if cmd == "encode" => {
            let mut input = String::new();
            std::io::stdin()
                .read_to_string(&mut input)
                .map_err(|e| format!("reading stdin: {e}"))?;
            let json: serde_json::Value =
                serde_json::from_str(&input).map_err(|e| format!("stdin is not JSON: {e}"))?;
            let bytes = causal_arm_msgs::json_to_cdr(ty, &json).map_err(|e| e.to_string())?;
            Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
        }
        [cmd, ty, hex] if cmd == "decode" => {
            let bytes = hex_decode(hex)?;
            let json = causal_arm_msgs::cdr_to_json(ty, &bytes).map_err(|e| e.to_string())?;
            Ok(json.to_string())
        }
        _ => Err(USAGE.to_owned()),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(out) => {
            println!("{out}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
