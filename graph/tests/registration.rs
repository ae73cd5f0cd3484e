//! A processor defined outside the processors crate: its own module and one
//! registration, and the registry, the graph and its outputs' descriptions know it.

use afe_core::{Error, ParamMap};
use afe_graph::Manager;
use afe_processors::Registry;

/// A processor of its own: the pre-processed ear signal, doubled.
mod doubled {
    use afe_core::{
        request_def, Block, Built, Descriptor, DrawAs, Ears, NoParams, Processor, RequestDef,
        Result, SignalInfo,
    };

    /// Doubles each sample of a time-domain signal.
    pub struct Doubled;

    impl Processor for Doubled {
        fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
            let x = inputs[0].as_slice();
            let out = outputs[0].resize_to(x.len());
            for (o, v) in out.iter_mut().zip(x) {
                *o = 2.0 * v;
            }
        }

        fn reset(&mut self) {}
    }

    impl Descriptor for Doubled {
        type Params = NoParams;
        const NAME: &'static str = "testDoubled";
        const DEPENDENCY: &'static str = "time";
        const EARS: Ears = Ears::PerEar;
        const DESCRIPTION: &'static str = "the pre-processed ear signal, doubled";
        const OUTPUT_UNIT: &'static str = "Pa";

        fn build(_: &NoParams, inputs: &[SignalInfo]) -> Result<Built> {
            let info = SignalInfo::time_domain(inputs[0].fs_hz)
                .with_unit(Self::OUTPUT_UNIT)
                .drawn_as(DrawAs::Signed);
            Ok(Built::new(Doubled, vec![info]))
        }
    }

    /// Its registry entry.
    pub static REQUEST: RequestDef = request_def::<Doubled>();

    /// A request computed from one that nobody registered.
    pub static ORPHAN: RequestDef = RequestDef {
        name: "testOrphan",
        dependency: "testNowhere",
        ..request_def::<Doubled>()
    };
}

#[test]
fn a_registered_processor_is_listed_found_and_computed() {
    let mut registry = Registry::default();
    let before = registry.requests().len();
    registry.register(&doubled::REQUEST).expect("a new name");
    assert_eq!(registry.requests().len(), before + 1);
    assert_eq!(registry.requests()[before].name, "testDoubled");
    let def = registry.find("testDoubled").expect("registered");
    assert_eq!((def.dependency, def.output_unit), ("time", "Pa"));

    let mut m = Manager::new(16000.0, 2).expect("manager");
    m.set_registry(registry.clone())
        .expect("before any request");
    let doubled = m
        .add_request("testDoubled", &ParamMap::new())
        .expect("placed");
    let time = m.add_request("time", &ParamMap::new()).expect("placed");
    assert!(
        m.set_registry(Registry::default()).is_err(),
        "a registry is set before the first request"
    );
    let left: Vec<f64> = (0..1600).map(|n| (n as f64 * 0.01).sin()).collect();
    let right: Vec<f64> = left.iter().map(|v| -0.5 * v).collect();
    m.process_chunk(&[&left, &right]).expect("processed");
    let ours = m.request_signals(doubled).expect("signals");
    let theirs = m.request_signals(time).expect("signals");
    assert_eq!(ours.len(), 2);
    for (o, t) in ours.iter().zip(&theirs) {
        assert_eq!(o.key(), format!("testDoubled_{}", o.channel.as_str()));
        assert_eq!((o.info.unit, o.info.display.as_str()), ("Pa", "signed"));
        assert_eq!(m.signal_chain(o.source)[0].0, "testDoubled");
        let twice: Vec<f64> = t.new.as_slice().iter().map(|v| 2.0 * v).collect();
        assert_eq!(o.new.as_slice(), twice.as_slice());
    }

    // another manager, with the built-in registry, does not know it
    let e = Manager::new(16000.0, 2)
        .expect("manager")
        .add_request("testDoubled", &ParamMap::new())
        .expect_err("not in its registry");
    assert!(e.to_string().contains("'testDoubled'"), "{e}");

    let again = registry
        .register(&doubled::REQUEST)
        .expect_err("the name is taken");
    assert!(
        matches!(&again, Error::RegistrationRefused { name, .. } if name == "testDoubled"),
        "{again}"
    );
    assert!(again.to_string().contains("already registered"), "{again}");
    let orphan = registry
        .register(&doubled::ORPHAN)
        .expect_err("an unknown dependency");
    assert!(
        orphan
            .to_string()
            .contains("'testNowhere' is not registered"),
        "{orphan}"
    );
    assert!(registry.find("testOrphan").is_err());
    assert_eq!(registry.requests().len(), before + 1);
}
