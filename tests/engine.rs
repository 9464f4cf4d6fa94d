//! The session engine on scripted traffic: negotiation, gaps, reboots, garbled and malformed
//! lines, lost replies, duplicates, and the ordering of outcomes.

use goniowatch::checks::alarm::{Affects, Alarm, AlarmCode, Handling};
use goniowatch::checks::Outcome;
use goniowatch::config::Config;
use goniowatch::engine::{Engine, Input, Output};
use goniowatch::fixtures::{self, Controller};
use goniowatch::protocol::{parse, ToController};

/// The command a line from the engine carries, with its sequence number.
fn command(line: &str) -> (u32, ToController) {
    let m = parse(line).unwrap();
    (m.seq, ToController::from_message(&m).unwrap())
}

/// config/sim.toml, the simulated rig's configuration, as text.
fn sim_toml() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sim.toml")).unwrap()
}

fn engine() -> Engine {
    Engine::from_config(&Config::from_toml_str(&sim_toml()).unwrap()).unwrap()
}

/// An engine on config/sim.toml with a probe round every `every` regular captures and no probe
/// entry configured (the pose is chosen).
fn probing_engine(every: u64) -> Engine {
    let text = sim_toml().replace("every = 0", &format!("every = {every}"));
    Engine::from_config(&Config::from_toml_str(&text).unwrap()).unwrap()
}

fn sent(out: &[Output]) -> Vec<String> {
    out.iter()
        .filter_map(|o| match o {
            Output::Send(l) => Some(
                parse(l).unwrap().verb
                    + &parse(l)
                        .unwrap()
                        .fields
                        .iter()
                        .map(|(k, v)| format!(" {k}={v}"))
                        .collect::<String>(),
            ),
            _ => None,
        })
        .collect()
}

fn alarms(out: &[Output]) -> Vec<String> {
    out.iter()
        .filter_map(|o| match o {
            Output::Alarm(a) => Some(a.code.to_string()),
            _ => None,
        })
        .collect()
}

/// The alarms with code `code`, in order.
fn alarms_with_code(out: &[Output], code: &str) -> Vec<Alarm> {
    out.iter()
        .filter_map(|o| match o {
            Output::Alarm(a) if a.code.as_str() == code => Some(a.clone()),
            _ => None,
        })
        .collect()
}

fn ok_outcome() -> Outcome {
    fixtures::ok_outcome([0.3, 0.3, 0.3])
}

fn connected(e: &mut Engine, c: &mut Controller) -> Vec<Output> {
    let mut out = e.handle(&Input::Connected);
    assert_eq!(sent(&out), vec!["HELLO proto=1 client=goniowatch/0.1.0"]);
    out.extend(e.handle(&c.ident(1)));
    out
}

#[test]
fn handshake_subscribes_and_resyncs_from_zero() {
    let (mut e, mut c) = (engine(), Controller::default());
    let out = connected(&mut e, &mut c);
    assert_eq!(
        sent(&out)[1..],
        ["SUBSCRIBE".to_string(), "RESYNC from=0".to_string()]
    );
    // the unsolicited IDENT after boot says the same: no second subscription
    let out = e.handle(&c.ident(1));
    assert!(sent(&out).is_empty());
}

#[test]
fn unsupported_version_is_critical() {
    let (mut e, mut c) = (engine(), Controller::default());
    e.handle(&Input::Connected);
    let out = e.handle(&c.line(
        "NAK",
        &[
            ("ref", "0".into()),
            ("reason", "unsupported-version".into()),
            ("supported", "2".into()),
        ],
    ));
    assert_eq!(alarms(&out), ["unsupported-version"]);
    let out = e.handle(&c.line("IDENT", &[("proto", "2".into()), ("boot", "1".into())]));
    assert_eq!(alarms(&out), ["unsupported-version"]);
    assert!(
        sent(&out).is_empty(),
        "nothing is subscribed on a version we do not speak"
    );
}

#[test]
fn garbled_lines_are_counted_and_never_fatal() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let mut out = Vec::new();
    for bad in [
        "",
        "garbage",
        "1 CAPTURE idx=1*FFFF",
        "\u{0}\u{1}\u{2}",
        &"x".repeat(2000),
        "12 CAPTURE idx=1 file=a*12G4",
    ] {
        out.extend(e.handle(&Input::Rx {
            line: bad.to_string(),
        }));
    }
    out.extend(e.handle(&Input::RxBad {
        reason: "line is not UTF-8".into(),
    }));
    assert_eq!(
        alarms(&out),
        ["crc-errors"],
        "a burst of bad lines is one link alarm"
    );
    let s = e.summary().link;
    assert_eq!(s.crc_errors + s.framing_errors, 7);
    // a CRC-valid CAPTURE with missing or bad fields is an alarm and a resync, not a crash
    let out = e.handle(&c.line("CAPTURE", &[("idx", "0".into()), ("entry", "zero".into())]));
    assert!(alarms(&out).contains(&"bad-announcement".to_string()));
    let out = e.handle(&c.line(
        "CAPTURE",
        &[
            ("idx", "0".into()),
            ("entry", "1".into()),
            ("file", "a".into()),
            ("t", "0".into()),
            ("cmd", "1,2,3".into()),
            ("enc", "1,2,3,4".into()),
        ],
    ));
    // the same capture malformed again after the resend: skipped, and checking goes on
    assert!(
        alarms(&out).contains(&"announcement-refused".to_string()),
        "{:?}",
        alarms(&out)
    );
    // unknown verbs are counted and ignored
    e.handle(&c.line("FROB", &[]));
    assert_eq!(e.summary().link.unknown_verbs, 1);
}

#[test]
fn sequence_gap_and_index_gap_trigger_resync_and_outcomes_go_in_order() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let ack = e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("count", "0".into()),
            ("next", "0".into()),
        ],
    ));
    assert!(sent(&ack).is_empty());
    let out = e.handle(&c.capture(0));
    assert!(matches!(out[0], Output::Ingest { idx: 0, .. }));
    c.seq += 1; // a lost line
    let out = e.handle(&c.capture(2)); // and an index gap
    assert_eq!(sent(&out), ["RESYNC from=1"]);
    assert_eq!(e.summary().link.sequence_gaps, 1);
    // outcome of 2 first: nothing is checked until 0 and 1 are in
    let out = e.handle(&Input::Outcome {
        idx: 2,
        outcome: ok_outcome(),
    });
    assert!(out.iter().all(|o| !matches!(o, Output::Capture(_))));
    e.handle(&c.capture(1));
    let out = e.handle(&Input::Outcome {
        idx: 1,
        outcome: ok_outcome(),
    });
    assert!(out.iter().all(|o| !matches!(o, Output::Capture(_))));
    let out = e.handle(&Input::Outcome {
        idx: 0,
        outcome: ok_outcome(),
    });
    let order: Vec<u64> = out
        .iter()
        .filter_map(|o| match o {
            Output::Capture(c) => Some(c.idx),
            _ => None,
        })
        .collect();
    assert_eq!(order, [0, 1, 2]);
}

#[test]
fn lost_ack_is_asked_again_after_64_lines_and_on_idle() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c); // RESYNC outstanding, its ACK never comes
    let mut resent = 0;
    for _ in 0..70 {
        let out = e.handle(&c.line(
            "POSE",
            &[
                ("t", "0".into()),
                ("cmd", "0,0,0,0".into()),
                ("enc", "0,0,0,0".into()),
            ],
        ));
        resent += sent(&out)
            .iter()
            .filter(|s| s.starts_with("RESYNC"))
            .count();
    }
    assert_eq!(resent, 1);
    let out = e.handle(&Input::Idle);
    assert_eq!(sent(&out), ["RESYNC from=0"]);
    // the ACK carries the state: a lost final STATUS is recovered
    let out = e.handle(&c.line(
        "ACK",
        &[
            ("ref", "4".into()),
            ("count", "0".into()),
            ("next", "0".into()),
            ("state", "done".into()),
        ],
    ));
    assert!(out.contains(&Output::Finished));
}

#[test]
fn reboot_resubscribes_and_duplicates_are_handled() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    e.handle(&c.capture(0));
    let mut c2 = Controller::default();
    let out = e.handle(&c2.ident(2));
    assert_eq!(alarms(&out), ["controller-reboot"]);
    assert_eq!(sent(&out), ["SUBSCRIBE", "RESYNC from=1"]);
    // a replayed announcement is harmless; a conflicting one is an alarm and the first is kept
    let again = e.handle(&c2.capture(0));
    assert!(again.is_empty());
    let conflicting = e.handle(&c2.line(
        "CAPTURE",
        &[
            ("idx", "0".into()),
            ("entry", "5".into()),
            ("file", "s/other.hdr".into()),
            ("t", "0".into()),
            ("cmd", "0,0,0,0".into()),
            ("enc", "0,0,0,0".into()),
        ],
    ));
    assert_eq!(alarms(&conflicting), ["duplicate-index"]);
    assert_eq!(e.summary().link.duplicate_announcements, 2);
}

#[test]
fn captures_missing_from_the_controller_log_are_reported_once() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    e.handle(&c.capture(0));
    e.handle(&c.capture(2));
    let out = e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("count", "0".into()),
            ("next", "3".into()),
        ],
    ));
    assert_eq!(alarms(&out), ["capture-never-announced"]);
    e.handle(&Input::Outcome {
        idx: 0,
        outcome: ok_outcome(),
    });
    let out = e.handle(&Input::Outcome {
        idx: 2,
        outcome: ok_outcome(),
    });
    assert!(
        out.iter()
            .any(|o| matches!(o, Output::Capture(c) if c.idx == 2)),
        "1 is skipped, 2 is checked"
    );
}

#[test]
fn disconnect_and_restart_are_link_events() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let out = e.handle(&Input::Disconnected {
        reason: "EIO".into(),
    });
    assert_eq!(alarms(&out), ["port-lost"]);
    assert!(e
        .active_conditions()
        .iter()
        .any(|a| a.code == AlarmCode::PortLost));
    let out = e.handle(&Input::Connected);
    assert_eq!(alarms(&out), ["port-back"]);
    let out = e.handle(&Input::Restart);
    assert_eq!(alarms(&out), ["daemon-restart"]);
    // nothing is sent while disconnected
    e.handle(&Input::Disconnected {
        reason: "EOF".into(),
    });
    assert!(sent(&e.handle(&Input::Idle)).is_empty());
}

#[test]
fn pause_on_critical_only_when_enabled() {
    let text = sim_toml();
    let text = text.replace("pause_on_critical = false", "pause_on_critical = true");
    let mut e = Engine::from_config(&Config::from_toml_str(&text).unwrap()).unwrap();
    let mut c = Controller::default();
    connected(&mut e, &mut c);
    let fault = c.line(
        "STATUS",
        &[
            ("state", "fault".into()),
            ("t", "1".into()),
            ("reason", "arm%20stall".into()),
        ],
    );
    let out = e.handle(&fault);
    assert_eq!(alarms(&out), ["controller-fault"]);
    assert_eq!(sent(&out), ["PAUSE"]);
    // off by default
    let mut e = engine();
    let mut c = Controller::default();
    connected(&mut e, &mut c);
    let out = e.handle(&c.line("STATUS", &[("state", "fault".into()), ("t", "1".into())]));
    assert_eq!(alarms(&out), ["controller-fault"]);
    assert!(sent(&out).is_empty());
}

fn capture_at(c: &mut Controller, idx: u64, entry: usize, pose: &str, replay: bool) -> Input {
    let mut f = vec![
        ("idx", idx.to_string()),
        ("entry", entry.to_string()),
        ("file", format!("s/cap_{idx}.hdr")),
        ("t", format!("{}", idx as f64 * 7.0)),
        ("cmd", pose.to_string()),
        ("enc", pose.to_string()),
        ("exp", "x".into()),
    ];
    if replay {
        f.push(("replay", "1".into()));
    }
    c.line("CAPTURE", &f)
}

#[test]
fn a_lost_hello_or_ident_is_asked_again() {
    let (mut e, mut c) = (engine(), Controller::default());
    e.handle(&Input::Connected);
    // the HELLO arrived corrupted
    let out = e.handle(&c.line("NAK", &[("ref", "-1".into()), ("reason", "bad-crc".into())]));
    assert_eq!(sent(&out), ["HELLO proto=1 client=goniowatch/0.1.0"]);
    // the IDENT was lost: the idle poll says HELLO again
    let out = e.handle(&Input::Idle);
    assert_eq!(sent(&out), ["HELLO proto=1 client=goniowatch/0.1.0"]);
    // the controller says we are not subscribed: subscribe again
    e.handle(&c.ident(1));
    let out = e.handle(&c.line(
        "NAK",
        &[("ref", "5".into()), ("reason", "not-subscribed".into())],
    ));
    assert_eq!(sent(&out)[0], "SUBSCRIBE");
}

#[test]
fn absurd_indices_from_the_wire_are_refused() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let t = std::time::Instant::now();
    let out = e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("next", "3000000".into()),
            ("state", "running".into()),
        ],
    ));
    assert!(alarms(&out).is_empty(), "an implausible next is ignored");
    assert!(t.elapsed() < std::time::Duration::from_secs(1));
    let out = e.handle(&capture_at(
        &mut c,
        1_000_000_000_000,
        1,
        "0,90,-90,15",
        false,
    ));
    assert_eq!(alarms(&out), ["bad-announcement"]);
    let out = e.handle(&capture_at(&mut c, u64::MAX, 1, "0,90,-90,15", false));
    assert_eq!(alarms(&out), ["bad-announcement"]);
    // the session can still finish
    e.handle(&c.capture(0));
    e.handle(&Input::Outcome {
        idx: 0,
        outcome: ok_outcome(),
    });
    let mut out = e.handle(&c.line(
        "STATUS",
        &[
            ("state", "done".into()),
            ("t", "9".into()),
            ("next", "1".into()),
        ],
    ));
    out.extend(e.handle(&Input::Idle));
    let r = out.iter().rev().find_map(|o| match o {
        Output::Send(l) => match command(l) {
            (seq, ToController::Resync { .. }) => Some(seq),
            _ => None,
        },
        _ => None,
    });
    if let Some(r) = r {
        e.handle(&c.line(
            "ACK",
            &[
                ("ref", r.to_string()),
                ("next", "1".into()),
                ("state", "done".into()),
            ],
        ));
    }
    assert!(e.is_finished());
    // many captures missing from the log make one alarm, not thousands
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let out = e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("next", "5000".into()),
            ("state", "running".into()),
        ],
    ));
    assert_eq!(alarms(&out), ["capture-never-announced"]);
}

#[test]
fn a_long_resync_reply_is_not_asked_again_midway() {
    // a controller like goniosim: RESYNC → every logged capture (replay=1), then the ACK
    let n_log = 1000u64;
    let (mut e, mut c) = (engine(), Controller::default());
    let mut wire: std::collections::VecDeque<Input> = Default::default();
    let mut pending = e.handle(&Input::Connected);
    let mut resyncs = 0;
    loop {
        for o in pending.drain(..) {
            if let Output::Send(l) = o {
                let (seq, cmd) = command(&l);
                match cmd {
                    ToController::Hello { .. } => wire.push_back(c.ident(1)),
                    ToController::Subscribe => {
                        wire.push_back(c.line("ACK", &[("ref", seq.to_string())]))
                    }
                    ToController::Resync { from } => {
                        resyncs += 1;
                        for i in from..n_log {
                            wire.push_back(capture_at(
                                &mut c,
                                i,
                                i as usize + 1,
                                "0,90,-90,15",
                                true,
                            ));
                        }
                        wire.push_back(c.line(
                            "ACK",
                            &[
                                ("ref", seq.to_string()),
                                ("count", "0".into()),
                                ("next", n_log.to_string()),
                                ("state", "running".into()),
                            ],
                        ));
                    }
                    _ => {}
                }
            }
        }
        let Some(inp) = wire.pop_front() else { break };
        pending = e.handle(&inp);
    }
    assert_eq!(resyncs, 1);
}

#[test]
fn a_retaken_entry_is_not_paired_twice() {
    let text = sim_toml();
    let cfg = Config::from_toml_str(&text).unwrap();
    let (plan, rig) = (
        goniowatch::setup::plan(&cfg).unwrap(),
        goniowatch::setup::rig(&cfg).unwrap(),
    );
    let a = 1usize;
    let b = plan.reciprocal_of(a).unwrap();
    let pose = |entry: usize| {
        let en = plan.entry(entry).unwrap();
        let d = plan.directions();
        let p = rig
            .plan_pose(d[en.light].spherical(), d[en.camera].spherical())
            .unwrap()
            .pose;
        format!(
            "{},{},{},{}",
            p.joints_deg[0], p.joints_deg[1], p.joints_deg[2], p.wagon_deg
        )
    };
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("next", "0".into()),
            ("state", "running".into()),
        ],
    ));
    let mut out = vec![];
    for (idx, entry) in [(0u64, a), (1, b), (2, b)] {
        out.extend(e.handle(&capture_at(&mut c, idx, entry, &pose(entry), false)));
        out.extend(e.handle(&Input::Outcome {
            idx,
            outcome: ok_outcome(),
        }));
    }
    assert_eq!(
        out.iter().filter(|o| matches!(o, Output::Pair(_))).count(),
        1
    );
    assert_eq!(e.table2().pairs, 1);
    assert!(alarms(&out).contains(&"entry-repeated".to_string()));
}

/// A connected engine whose RESYNC the controller answered: running, next capture 0.
fn connected_and_running(e: &mut Engine) -> Controller {
    let mut c = Controller::default();
    connected(e, &mut c);
    e.handle(&c.line(
        "ACK",
        &[
            ("ref", "2".into()),
            ("next", "0".into()),
            ("state", "running".into()),
        ],
    ));
    c
}

/// A capture line and its outcome, as a controller and the decoder would hand them over.
fn feed_capture(
    e: &mut Engine,
    c: &mut Controller,
    ci: goniowatch::checks::CaptureInput,
) -> Vec<Output> {
    let (idx, outcome) = (ci.idx, ci.outcome.clone());
    let mut got = announce_capture(e, c, &ci);
    got.extend(e.handle(&Input::Outcome { idx, outcome }));
    got
}

/// The controller's line announcing a capture, without its outcome (the file not yet decoded).
fn announce_capture(
    e: &mut Engine,
    c: &mut Controller,
    ci: &goniowatch::checks::CaptureInput,
) -> Vec<Output> {
    let pose = |p: [f64; 4]| p.map(|v| v.to_string()).join(",");
    let mut f = vec![
        ("idx", ci.idx.to_string()),
        ("entry", ci.entry.to_string()),
        ("file", ci.file.clone()),
        ("t", ci.t.to_string()),
        ("cmd", pose(ci.cmd)),
        ("enc", pose(ci.enc)),
        ("exp", "x".into()),
    ];
    if let Some(sub) = ci.substitute {
        f.push(("sub", sub.to_string()));
    }
    if ci.probe {
        f.push(("probe", "1".into()));
    }
    e.handle(&c.line("CAPTURE", &f))
}

/// The PROBE lines an engine sent.
fn probes_sent(out: &[Output]) -> Vec<String> {
    sent(out)
        .into_iter()
        .filter(|s| s.starts_with("PROBE"))
        .collect()
}

#[test]
fn probes_are_requested_only_when_enabled() {
    let text = sim_toml();
    let cfg = Config::from_toml_str(
        &text
            .replace("every = 0", "every = 2")
            .replace("# entry = 19", "entry = 19"),
    )
    .unwrap();
    let plan = goniowatch::setup::plan(&cfg).unwrap();
    let entry = goniowatch::setup::probe_entry(&cfg, &plan).unwrap();
    let e0 = plan.entry(entry).unwrap();
    assert_eq!(plan.directions()[e0.light].theta_deg, 0.0);
    assert_eq!(plan.directions()[e0.camera].theta_deg, 45.0);
    for (every, want) in [(2u64, 1usize), (0, 0)] {
        let mut e = if every > 0 {
            Engine::from_config(&cfg).unwrap()
        } else {
            engine()
        };
        let mut c = connected_and_running(&mut e);
        let mut out = Vec::new();
        for i in 0..2 {
            out.extend(e.handle(&c.capture(i)));
            out.extend(e.handle(&Input::Outcome {
                idx: i,
                outcome: ok_outcome(),
            }));
        }
        let probes = probes_sent(&out);
        assert_eq!(probes.len(), want, "every {every}");
        if want > 0 {
            assert_eq!(probes[0], format!("PROBE entry={entry}"));
        }
    }
    let bad = Config::from_toml_str(
        &text
            .replace("every = 0", "every = 2")
            .replace("# entry = 19", "entry = 99999"),
    );
    assert!(bad.is_err_and(|e| e.to_string().contains("probes.entry")));
}

/// A controller that refuses `PROBE` (or does not know it) gets one `probes-refused` warning and
/// no more probe rounds; a refusal of any other command does not touch the probes.
#[test]
fn a_refused_probe_withdraws_the_probes_with_one_warning() {
    let cfg = Config::from_toml_str(
        &sim_toml()
            .replace("every = 0", "every = 2")
            .replace("# entry = 19", "entry = 19"),
    )
    .unwrap();
    for reason in ["refused", "unknown-verb"] {
        let mut e = Engine::from_config(&cfg).unwrap();
        let mut c = connected_and_running(&mut e);
        let mut out = Vec::new();
        for i in 0..2 {
            out.extend(e.handle(&c.capture(i)));
            out.extend(e.handle(&Input::Outcome {
                idx: i,
                outcome: ok_outcome(),
            }));
        }
        let probe_seq = out
            .iter()
            .find_map(|o| match o {
                Output::Send(l) if parse(l).unwrap().verb == "PROBE" => Some(parse(l).unwrap().seq),
                _ => None,
            })
            .expect("a probe round at 2 captures");
        // a NAK of another command leaves the probes on
        let other = e.handle(&c.line(
            "NAK",
            &[
                ("ref", (probe_seq + 1000).to_string()),
                ("reason", reason.into()),
            ],
        ));
        assert!(!other.iter().any(|o| matches!(o, Output::Alarm(_))));
        let refused = e.handle(&c.line(
            "NAK",
            &[("ref", probe_seq.to_string()), ("reason", reason.into())],
        ));
        let alarms: Vec<_> = refused
            .iter()
            .filter_map(|o| match o {
                Output::Alarm(a) => Some(a),
                _ => None,
            })
            .collect();
        assert_eq!(alarms.len(), 1, "{reason}");
        assert_eq!(alarms[0].code, AlarmCode::ProbesRefused);
        assert_eq!(
            alarms[0].evidence.to_json(),
            serde_json::json!({"reason": reason, "probes_taken": 0})
        );
        let mut after = Vec::new();
        for i in 2..12 {
            after.extend(e.handle(&c.capture(i)));
            after.extend(e.handle(&Input::Outcome {
                idx: i,
                outcome: ok_outcome(),
            }));
        }
        assert!(
            probes_sent(&after).is_empty(),
            "{reason}: {:?}",
            probes_sent(&after)
        );
        // said once: a late second refusal of the same round raises nothing
        let again = e.handle(&c.line(
            "NAK",
            &[("ref", probe_seq.to_string()), ("reason", reason.into())],
        ));
        assert!(!again.iter().any(|o| matches!(o, Output::Alarm(_))));
    }
}

#[test]
fn without_a_configured_entry_the_probe_pose_is_chosen_after_a_sweep_and_then_probed() {
    let cfg = Config::from_toml_str(&sim_toml().replace("every = 0", "every = 10")).unwrap();
    assert_eq!(cfg.probes.entry, None);
    let mut e = Engine::from_config(&cfg).unwrap();
    let mut c = connected_and_running(&mut e);
    let mut out = Vec::new();
    // the first 100 captures of the plan: the pole light's sweep (81) and 19 more
    for ci in fixtures::ubo_session(100, |_| 1.0) {
        out.extend(feed_capture(&mut e, &mut c, ci));
    }
    let chosen: Vec<_> = out
        .iter()
        .filter_map(|o| match o {
            Output::ProbePose(p) => Some(*p),
            _ => None,
        })
        .collect();
    assert_eq!(chosen.len(), 1, "chosen once");
    let p = chosen[0];
    // from the pole light's sweep: off grazing and off the mirror direction
    assert!(p.entry < 81 && p.theta_i_deg < 1e-6, "{p:?}");
    assert!(
        p.theta_o_deg <= 45.0 + 1e-9 && p.specular_distance_deg >= 25.0,
        "{p:?}"
    );
    // no probe before a sweep's worth was checked: the round due since 10 captures as soon as
    // the pose is chosen (at 81), then at 90 and 100
    assert_eq!(
        probes_sent(&out),
        vec![format!("PROBE entry={}", p.entry); 3]
    );
    assert_eq!(e.summary().probe_pose, Some(p));
}

#[test]
fn probes_keep_the_rigs_cadence_when_checking_lags_behind_the_announcements() {
    let mut e = probing_engine(10);
    let mut c = connected_and_running(&mut e);
    let session = fixtures::ubo_session(140, |_| 1.0);
    // the controller announces 120 captures before any of their files is decoded: the pose is
    // not known yet, so no round can be asked for
    let mut out = Vec::new();
    for ci in &session[..120] {
        out.extend(announce_capture(&mut e, &mut c, ci));
    }
    assert!(probes_sent(&out).is_empty());
    // checking catches up: the pose is chosen at 81 checked, and the round that is overdue is
    // asked for at once, and only once (the next is due at 130 announced)
    let mut out = Vec::new();
    let mut asked_at = Vec::new();
    for ci in &session[..120] {
        let got = e.handle(&Input::Outcome {
            idx: ci.idx,
            outcome: ci.outcome.clone(),
        });
        if !probes_sent(&got).is_empty() {
            asked_at.push(ci.idx);
        }
        out.extend(got);
    }
    assert_eq!(asked_at, vec![80], "{:?}", probes_sent(&out));
    // from then on each round is asked for when the controller announces the 130th and 140th
    // regular capture, before their files are decoded
    let mut asked_on_announcement = Vec::new();
    for ci in &session[120..] {
        if !probes_sent(&announce_capture(&mut e, &mut c, ci)).is_empty() {
            asked_on_announcement.push(ci.idx);
        }
        e.handle(&Input::Outcome {
            idx: ci.idx,
            outcome: ci.outcome.clone(),
        });
    }
    assert_eq!(asked_on_announcement, vec![129, 139]);
}

#[test]
fn a_probe_pose_that_cannot_be_chosen_is_said_once_and_no_probe_is_asked_for() {
    let mut e = probing_engine(10);
    let mut c = connected_and_running(&mut e);
    let mut out = Vec::new();
    // every capture at the same pose, off its plan entry's: none can be a probe pose
    for i in 0..170 {
        out.extend(e.handle(&c.capture(i)));
        out.extend(e.handle(&Input::Outcome {
            idx: i,
            outcome: ok_outcome(),
        }));
    }
    let said = alarms(&out)
        .iter()
        .filter(|a| *a == "probe-pose-unavailable")
        .count();
    assert_eq!(said, 1, "{:?}", alarms(&out));
    assert!(probes_sent(&out).is_empty());
    assert_eq!(e.summary().probe_pose, None);
}

/// The RESYNCs an engine sent.
fn resyncs(out: &[Output]) -> usize {
    sent(out).iter().filter(|l| l.starts_with("RESYNC")).count()
}

/// A controller that answers every RESYNC by resending its capture log from `from`, where
/// capture `bad` is an intact line (valid CRC) with a bad `%` escape in `file`.
fn hostile_replay(
    e: &mut Engine,
    c: &mut Controller,
    out: &[Output],
    bad: u64,
    next: u64,
) -> Vec<Output> {
    let mut got = Vec::new();
    for o in out {
        let Output::Send(l) = o else { continue };
        let (seq, ToController::Resync { from }) = command(l) else {
            continue;
        };
        for i in from..next {
            let line = if i == bad {
                let p = format!(
                    "{} CAPTURE idx={i} entry={} file=s/cap_%ZZ.hdr t=7 cmd=0,90,-90,15 enc=0,90,-90,15 exp=x replay=1",
                    c.seq,
                    i + 1
                );
                c.seq += 1;
                Input::Rx {
                    line: format!("{p}*{:04X}", goniowatch::protocol::crc16(p.as_bytes())),
                }
            } else {
                c.capture(i)
            };
            got.extend(e.handle(&line));
        }
        let ack = c.line(
            "ACK",
            &[
                ("ref", seq.to_string()),
                ("count", "0".into()),
                ("next", next.to_string()),
                ("state", "running".into()),
            ],
        );
        got.extend(e.handle(&ack));
    }
    got
}

#[test]
fn an_intact_but_unacceptable_capture_line_is_skipped_after_one_resend() {
    let (mut e, mut c) = (engine(), Controller::default());
    let out = connected(&mut e, &mut c);
    let mut all = hostile_replay(&mut e, &mut c, &out, 1, 0);
    // live traffic: capture 0, the bad capture 1, then captures 2..40
    for i in 0..40u64 {
        let next = i + 1;
        let out = if i == 1 {
            let p = format!(
                "{} CAPTURE idx=1 entry=2 file=s/cap_%ZZ.hdr t=7 cmd=0,90,-90,15 enc=0,90,-90,15 exp=x",
                c.seq
            );
            c.seq += 1;
            e.handle(&Input::Rx {
                line: format!("{p}*{:04X}", goniowatch::protocol::crc16(p.as_bytes())),
            })
        } else {
            e.handle(&c.capture(i))
        };
        all.extend(out.clone());
        // the controller answers each RESYNC at once, the bad line included
        let mut pending = out;
        for _ in 0..10 {
            let got = hostile_replay(&mut e, &mut c, &pending, 1, next);
            if got.is_empty() {
                break;
            }
            all.extend(got.clone());
            pending = got;
        }
    }
    assert!(
        resyncs(&all) <= 3,
        "one resend is asked, not a loop: {} RESYNCs",
        resyncs(&all)
    );
    let codes = alarms(&all);
    assert_eq!(
        codes.iter().filter(|c| *c == "bad-announcement").count(),
        1,
        "{codes:?}"
    );
    assert_eq!(
        codes
            .iter()
            .filter(|c| *c == "announcement-refused")
            .count(),
        1,
        "{codes:?}"
    );
    assert_eq!(
        e.summary().link.sequence_gaps,
        0,
        "an intact line's seq counts"
    );
    // checking goes on past the skipped capture
    for i in (0..40u64).filter(|i| *i != 1) {
        e.handle(&Input::Outcome {
            idx: i,
            outcome: ok_outcome(),
        });
    }
    assert_eq!(e.checked_through(), 40);
}

#[test]
fn resyncs_for_the_same_capture_back_off() {
    let (mut e, mut c) = (engine(), Controller::default());
    let out = connected(&mut e, &mut c);
    assert_eq!(resyncs(&out), 1);
    // every ACK is lost and every line arrives after a sequence gap: without a backoff each
    // line would ask again
    let mut n = resyncs(&out);
    for _ in 0..20_000 {
        c.seq += 1; // a gap before every line
        n += resyncs(&e.handle(&c.line("POSE", &[])));
    }
    assert!(
        n < 40,
        "{n} RESYNCs for 20,000 lines: the backoff bounds them"
    );
    assert!(n >= 10, "{n}: still asked now and then");
    // the idle timer asks at once, whatever the backoff
    assert_eq!(resyncs(&e.handle(&Input::Idle)), 1);
}

#[test]
fn alarm_storms_are_aggregated_and_every_occurrence_is_counted() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let mut out = Vec::new();
    for _ in 0..10_000 {
        let p = format!("{} POSE t=%ZZ", c.seq);
        c.seq += 1;
        out.extend(e.handle(&Input::Rx {
            line: format!("{p}*{:04X}", goniowatch::protocol::crc16(p.as_bytes())),
        }));
    }
    let emitted: Vec<&goniowatch::checks::alarm::Alarm> = out
        .iter()
        .filter_map(|o| match o {
            Output::Alarm(a) if a.code == AlarmCode::BadLine => Some(a),
            _ => None,
        })
        .collect();
    assert!(
        emitted.len() <= 6 * (10_000 / 2000 + 1),
        "{} bad-line alarms written for 10,000 lines",
        emitted.len()
    );
    let held: u64 = emitted
        .iter()
        .filter_map(|a| {
            a.evidence
                .to_json()
                .get("aggregated")
                .and_then(|v| v.as_u64())
        })
        .sum();
    let full = emitted
        .iter()
        .filter(|a| a.evidence.to_json().get("aggregated").is_none())
        .count() as u64;
    // what is written in full or as a count adds up to what was seen, but for the last window
    // (2,000 inputs), which is still open
    assert!(
        full + held <= 10_000 && full + held >= 8_000,
        "{full} + {held}"
    );
    assert_eq!(e.summary().alarms.get("link"), Some(&10_000));
}

#[test]
fn absurd_controller_times_are_refused() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    for t in ["1e308", "-1e308", "-5"] {
        let out = e.handle(&c.line(
            "CAPTURE",
            &[
                ("idx", "0".into()),
                ("entry", "1".into()),
                ("file", "a.hdr".into()),
                ("t", t.into()),
                ("cmd", "0,90,-90,15".into()),
                ("enc", "0,90,-90,15".into()),
            ],
        ));
        assert!(
            out.iter().all(|o| !matches!(o, Output::Ingest { .. })),
            "t = {t} accepted"
        );
    }
}

#[test]
fn a_critical_raised_before_a_resume_still_counts_for_the_exit_status() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    assert!(!e.critical_raised());
    let fault = c.line("STATUS", &[("state", "fault".into()), ("t", "1".into())]);
    let out = e.handle(&fault);
    assert_eq!(alarms(&out), ["controller-fault"]);
    assert!(e.critical_raised());
    // a resumed daemon rebuilds the engine from the journal without carrying out its alarms
    // again; the exit status comes from the rebuilt engine, not from the alarms it emits now
    let mut resumed = engine();
    let mut c2 = Controller::default();
    connected(&mut resumed, &mut c2);
    resumed.handle(&fault);
    let out = resumed.handle(&Input::Restart);
    assert!(!alarms(&out).contains(&"controller-fault".to_string()));
    assert!(resumed.critical_raised());
}

#[test]
fn a_malformed_line_inside_a_resync_answer_is_asked_again_not_taken_as_lost() {
    for second_copy_readable in [false, true] {
        let (mut e, mut c) = (engine(), Controller::default());
        let out = connected(&mut e, &mut c);
        let mut all = hostile_replay(&mut e, &mut c, &out, u64::MAX, 0);
        all.extend(e.handle(&c.capture(0)));
        // the live line for capture 1 is lost; capture 2 arrives after the gap
        c.seq += 1;
        let out = e.handle(&c.capture(2));
        assert_eq!(resyncs(&out), 1);
        all.extend(out.clone());
        // the controller's answer carries capture 1 malformed
        let out = hostile_replay(&mut e, &mut c, &out, 1, 3);
        all.extend(out.clone());
        let codes = alarms(&all);
        assert!(
            !codes.iter().any(|c| c == "capture-never-announced"),
            "capture 1 is in the controller's log: {codes:?}"
        );
        assert_eq!(resyncs(&out), 1, "capture 1 is asked for again");
        // the second answer: malformed again, or readable this time
        let bad = if second_copy_readable { u64::MAX } else { 1 };
        all.extend(hostile_replay(&mut e, &mut c, &out, bad, 3));
        let codes = alarms(&all);
        assert!(
            !codes.iter().any(|c| c == "capture-never-announced"),
            "{codes:?}"
        );
        let refused = codes
            .iter()
            .filter(|c| *c == "announcement-refused")
            .count();
        assert_eq!(refused, usize::from(!second_copy_readable), "{codes:?}");
        for i in 0..3u64 {
            e.handle(&Input::Outcome {
                idx: i,
                outcome: ok_outcome(),
            });
        }
        assert_eq!(e.checked_through(), 3);
        assert_eq!(
            e.summary().checked.ok,
            3 - refused as u64,
            "{second_copy_readable}"
        );
    }
}

#[test]
fn an_announced_exposure_is_divided_out_and_a_bad_one_is_refused() {
    let (mut e, mut c) = (engine(), Controller::default());
    connected(&mut e, &mut c);
    let line = |c: &mut Controller, idx: u64, exposure: &str| {
        c.line(
            "CAPTURE",
            &[
                ("idx", idx.to_string()),
                ("entry", (idx + 1).to_string()),
                ("file", format!("s/cap_{idx}.png")),
                ("t", format!("{}", idx as f64 * 7.0)),
                ("cmd", "0,90,-90,15".into()),
                ("enc", "0,90,-90,15".into()),
                ("exp", "x".into()),
                ("exposure", exposure.into()),
            ],
        )
    };
    e.handle(&line(&mut c, 0, "2"));
    let out = e.handle(&Input::Outcome {
        idx: 0,
        outcome: fixtures::ok_outcome([0.4, 0.2, 0.6]),
    });
    let rec = out
        .iter()
        .find_map(|o| match o {
            Output::Capture(r) => Some(r.clone()),
            _ => None,
        })
        .unwrap();
    assert_eq!(rec.mean_rgb, Some([0.2, 0.1, 0.3]), "{rec:?}");
    // zero, negative or not a number: the announcement is malformed (asked again, not guessed)
    for bad in ["0", "-1", "x", "inf"] {
        let (mut e, mut c) = (engine(), Controller::default());
        connected(&mut e, &mut c);
        let out = e.handle(&line(&mut c, 0, bad));
        assert!(
            !out.iter().any(|o| matches!(o, Output::Ingest { .. })),
            "{bad}: not taken"
        );
        assert!(
            sent(&out).iter().any(|l| l.starts_with("RESYNC"))
                || alarms(&out).contains(&"bad-announcement".to_string()),
            "{bad}: {:?} {:?}",
            sent(&out),
            alarms(&out)
        );
    }
}

#[test]
fn a_daemon_behind_a_finished_controller_finishes_on_late_answers_or_without_the_link() {
    // the controller announces three captures and says it is done; the daemon's outcomes come
    // later (it is behind), the quiet link's idle ticks send RESYNCs, and their ACKs arrive
    // late, all at once, after a newer RESYNC replaced the ones they answer
    for lose_the_link in [false, true] {
        let (mut e, mut c) = (engine(), Controller::default());
        connected(&mut e, &mut c);
        e.handle(&c.line(
            "ACK",
            &[
                ("ref", "2".into()),
                ("count", "0".into()),
                ("next", "0".into()),
            ],
        ));
        for idx in 0..3 {
            e.handle(&capture_at(&mut c, idx, idx as usize, "0,0,0,0", false));
        }
        e.handle(&c.line(
            "STATUS",
            &[
                ("state", "done".into()),
                ("t", "21".into()),
                ("next", "3".into()),
            ],
        ));
        let mut refs = Vec::new();
        for _ in 0..4 {
            for l in sent(&e.handle(&Input::Idle)) {
                assert!(l.starts_with("RESYNC"), "{l}");
                refs.push(l);
            }
        }
        assert!(refs.len() >= 2, "{refs:?}");
        for idx in 0..2 {
            e.handle(&Input::Outcome {
                idx,
                outcome: ok_outcome(),
            });
        }
        if lose_the_link {
            // the controller leaves before answering: the link is no reason to wait
            e.handle(&Input::Disconnected {
                reason: "end of stream".into(),
            });
        } else {
            // the answer to the first idle RESYNC (sequence 3 after HELLO, SUBSCRIBE, RESYNC)
            e.handle(&c.line(
                "ACK",
                &[
                    ("ref", "3".into()),
                    ("count", "0".into()),
                    ("next", "3".into()),
                    ("state", "done".into()),
                ],
            ));
        }
        assert!(!e.is_finished());
        let out = e.handle(&Input::Outcome {
            idx: 2,
            outcome: ok_outcome(),
        });
        assert!(
            out.contains(&Output::Finished),
            "lose the link: {lose_the_link}"
        );
    }
}

/// An anisotropic sample on the UBO plan with probes every 100 captures, arm joint 3 turned by
/// `turn` from regular capture `onset` on: the engine and a controller that takes every PROBE
/// it is asked for right after the capture that asked, or (`late_sentinel`) takes a round's
/// lamp probe then, and its sentinel only after the next regular capture, as a controller does
/// that reads the round's second command late. All outputs, in order.
fn anisotropic_run(
    captures: usize,
    onset: usize,
    turn: f64,
    late_sentinel: bool,
) -> (Engine, Vec<Output>) {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/sim-anisotropic.toml"
    ))
    .unwrap();
    let cfg = Config::from_toml_str(&text.replace("every = 0", "every = 100")).unwrap();
    assert!(!cfg.sample.isotropic && cfg.probes.sentinel);
    let mut e = Engine::from_config(&cfg).unwrap();
    let mut c = connected_and_running(&mut e);
    let mut out = Vec::new();
    let mut idx = 0u64;
    let mut held: Vec<usize> = Vec::new();
    for entry in 0..captures {
        let t = idx as f64 * 7.0;
        let deg = if entry >= onset { turn } else { 0.0 };
        let ci = fixtures::anisotropic_capture(idx, entry, t, deg, false).unwrap();
        idx += 1;
        let got = feed_capture(&mut e, &mut c, ci);
        let mut asked: Vec<usize> = std::mem::take(&mut held);
        for (k, p) in probes_sent(&got)
            .iter()
            .map(|l| l.trim_start_matches("PROBE entry=").parse().unwrap())
            .enumerate()
        {
            if late_sentinel && k > 0 {
                held.push(p);
            } else {
                asked.push(p);
            }
        }
        out.extend(got);
        for p in asked {
            let t = idx as f64 * 7.0;
            let ci = fixtures::anisotropic_capture(idx, p, t, deg, true).unwrap();
            idx += 1;
            out.extend(feed_capture(&mut e, &mut c, ci));
        }
    }
    (e, out)
}

#[test]
fn on_an_anisotropic_sample_a_sentinel_probe_follows_each_probe_and_names_a_turn_of_joint_3() {
    // (named at the second round after the turn: one departing reading is not enough)
    // joint 3 turns by +1° at regular capture 1,500; probes every 100
    let (e, out) = anisotropic_run(2300, 1500, 1.0, false);
    let sentinels: Vec<_> = out
        .iter()
        .filter_map(|o| match o {
            Output::SentinelPose(p) => Some(*p),
            _ => None,
        })
        .collect();
    assert_eq!(sentinels.len(), 1, "chosen once");
    let s = sentinels[0];
    // from the pole light's sweep, on a flank of the anisotropy: steep to joint 3
    assert!(
        s.entry < 81 && s.sensitivity_pct_per_deg.abs() > 1.0,
        "{s:?}"
    );
    let lamp = e.summary().probe_pose.unwrap().entry;
    assert_ne!(lamp, s.entry);
    // every probe round is the lamp probe, then the sentinel
    let probes = probes_sent(&out);
    assert!(probes.len() >= 2 * 20, "{probes:?}");
    for pair in probes.chunks(2) {
        assert_eq!(
            pair,
            [
                format!("PROBE entry={lamp}"),
                format!("PROBE entry={}", s.entry)
            ]
        );
    }
    // named as joint 3 with the right sign
    let named = alarms_with_code(&out, "joint-offset-suspected");
    assert_eq!(named.len(), 1, "{named:?}");
    let a = &named[0];
    assert_eq!(a.evidence.to_json()["joint"], 3);
    let est = a.evidence.to_json()["offset_deg"].as_f64().unwrap();
    assert!((0.7..1.3).contains(&est), "{est}");
    // regular capture 1,500 is capture 1,500 + 2 × 15 probes in; the round after regular
    // capture 1,600 departs and the one after 1,700 confirms it
    let at = a.idx.unwrap();
    assert!((1730..=1740).contains(&at), "{at}");
    let Some(Affects::Since {
        from_idx,
        handling: Handling::Retake,
    }) = a.affects
    else {
        panic!("{a:?}");
    };
    assert!(from_idx <= 1530, "{from_idx}");
    assert!(a.action.as_deref().unwrap().contains("joint 3"));
    let summary = e.summary().joint3_sentinel.unwrap();
    assert!((summary.offset_deg - 1.0).abs() < 0.3, "{summary:?}");
    // the lamp is steady: no drift alarm
    assert!(
        !alarms(&out).iter().any(|c| c.starts_with("gain-")),
        "{:?}",
        alarms(&out)
    );
}

#[test]
fn a_sentinel_taken_a_capture_after_its_lamp_probe_still_names_the_turn_at_the_same_round() {
    // the controller reads each round's second PROBE late: one regular capture falls between
    // the lamp probe and the sentinel, and every reading still counts
    let (e, out) = anisotropic_run(2300, 1500, 1.0, true);
    let named = alarms_with_code(&out, "joint-offset-suspected");
    assert_eq!(named.len(), 1, "{named:?}");
    let est = named[0].evidence.to_json()["offset_deg"].as_f64().unwrap();
    assert!((0.7..1.3).contains(&est), "{est}");
    // the round asked after regular capture 1,499 takes its sentinel after 1,500, the first
    // turned one: that reading departs, and the next round's (after regular capture 1,600,
    // which is capture 1,600 + 2 × 16 probes in) confirms it
    let at = named[0].idx.unwrap();
    assert!((1630..=1640).contains(&at), "{at}");
    let s = e.summary().joint3_sentinel.unwrap();
    // every sentinel taken is read (the last round's is still held when the run ends)
    let rounds = probes_sent(&out).len() / 2;
    assert_eq!(s.readings, rounds - 1, "{s:?}");
}

#[test]
fn a_steady_anisotropic_sample_keeps_its_sentinel_quiet_and_an_isotropic_one_has_none() {
    let (e, out) = anisotropic_run(2300, usize::MAX, 0.0, false);
    assert!(
        !alarms(&out).iter().any(|c| c == "joint-offset-suspected"),
        "{:?}",
        alarms(&out)
    );
    let s = e.summary().joint3_sentinel.unwrap();
    assert!(s.readings >= 20 && s.offset_deg.abs() < 0.05, "{s:?}");
    // an isotropic sample (config/sim.toml) probes the lamp only: see
    // without_a_configured_entry_the_probe_pose_is_chosen_after_a_sweep_and_then_probed
}

#[test]
fn a_sample_without_a_pose_sensitive_to_joint_3_says_so_once_and_probes_the_lamp_only() {
    // declared anisotropic, but the captures are of an isotropic BRDF: no pole-light pose
    // changes with joint 3
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/sim-anisotropic.toml"
    ))
    .unwrap();
    let cfg = Config::from_toml_str(&text.replace("every = 0", "every = 100")).unwrap();
    let mut e = Engine::from_config(&cfg).unwrap();
    let mut c = connected_and_running(&mut e);
    let mut out = Vec::new();
    for ci in fixtures::ubo_session(400, |_| 1.0) {
        out.extend(feed_capture(&mut e, &mut c, ci));
    }
    let said = alarms(&out)
        .iter()
        .filter(|a| *a == "joint3-sentinel-unavailable")
        .count();
    assert_eq!(said, 1, "{:?}", alarms(&out));
    assert!(!out.iter().any(|o| matches!(o, Output::SentinelPose(_))));
    let lamp = e.summary().probe_pose.unwrap().entry;
    let probes = probes_sent(&out);
    assert!(!probes.is_empty());
    assert!(
        probes.iter().all(|p| *p == format!("PROBE entry={lamp}")),
        "{probes:?}"
    );
    assert!(e.summary().joint3_sentinel.is_none());
    assert!(e
        .summary()
        .observability
        .blind
        .iter()
        .any(|b| b.what.contains("joints 1, 2 and 3")));
}

/// The archive controller and the engine with the engine's first RESYNC held back until the
/// controller has announced a whole full-size listing live (the order a slow first listing of a
/// 6,561-file folder gives): the RESYNC is answered once, the engine does not ask again for
/// every 64 live lines, and the lines exchanged stay linear in the set.
#[test]
fn a_resync_behind_a_full_size_first_listing_does_not_cascade() {
    use goniowatch::archive::controller::ArchiveController;
    use goniowatch::archive::listing::ArchiveCapture;
    use std::collections::VecDeque;
    const N: usize = 6561;
    let mut e = engine();
    let mut ctl = ArchiveController::new("set", N);
    let mut to_ctl: VecDeque<String> = VecDeque::new();
    let sends = |out: Vec<Output>, q: &mut VecDeque<String>| {
        for o in out {
            if let Output::Send(l) = o {
                q.push_back(l);
            }
        }
    };
    sends(e.handle(&Input::Connected), &mut to_ctl);
    ctl.handle_connect();
    // every line the controller has queued goes to the engine; returns (lines, RESYNCs sent)
    fn pump(
        e: &mut Engine,
        ctl: &mut ArchiveController,
        q: &mut VecDeque<String>,
    ) -> (usize, usize) {
        let (mut lines, mut resyncs) = (0, 0);
        while let Some(line) = ctl.poll_line() {
            lines += 1;
            for o in e.handle(&Input::Rx { line }) {
                if let Output::Send(l) = o {
                    if matches!(command(&l).1, ToController::Resync { .. }) {
                        resyncs += 1;
                    }
                    q.push_back(l);
                }
            }
        }
        (lines, resyncs)
    }
    let (mut from_ctl, mut resyncs) = (0usize, 0usize);
    // IDENT → SUBSCRIBE, RESYNC from=0
    let (l, r) = pump(&mut e, &mut ctl, &mut to_ctl);
    from_ctl += l;
    resyncs += r;
    assert_eq!(resyncs, 1);
    // the SUBSCRIBE reaches the controller; the RESYNC waits behind the first listing
    let mut held = VecDeque::new();
    while let Some(line) = to_ctl.pop_front() {
        if matches!(command(&line).1, ToController::Resync { .. }) {
            held.push_back(line);
        } else {
            ctl.handle_line(&line);
        }
    }
    assert_eq!(held.len(), 1);
    to_ctl = held;
    for entry in 0..N {
        ctl.handle_capture(ArchiveCapture {
            file: format!("cap_{entry:05}.hdr"),
            entry,
            t: entry as f64 * 7.0,
            pose: [0.0, 90.0, -90.0, 15.0],
            sub: None,
            exposure: None,
        });
    }
    ctl.handle_end();
    // from here on every line is delivered as soon as it is sent
    loop {
        let (l, r) = pump(&mut e, &mut ctl, &mut to_ctl);
        from_ctl += l;
        resyncs += r;
        let Some(line) = to_ctl.pop_front() else {
            break;
        };
        ctl.handle_line(&line);
    }
    assert!(resyncs <= 2, "{resyncs} RESYNCs");
    assert!(from_ctl <= 2 * N + 20, "{from_ctl} lines for {N} captures");
    assert_eq!(e.summary().captures_announced, N as u64);
}
