//! The board around the plant, behind the firmware's hardware traits (`hal`).

use hal::{
    AbsolutePositions, Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage,
    QuadratureCounter, SafeOutputs, SafetyChain,
};
use plant::{Plant, PlantError, NUM_JOINTS};

use crate::layout::Layout;

/// The step of [`BoardOnPlant::step_ms`], s (ten per millisecond).
pub const STEP_S: f64 = 1e-4;

/// How the robot's motors, encoders, switches and brakes are wired to the board: the
/// straight wiring ([`Wiring::default`]) is the pin map's; each other value is a
/// miswiring a robot just built may have, injectable on any joint (commissioning finds
/// them, `control::commissioning`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wiring {
    /// The motor's leads reversed: a positive duty drives the joint towards -q (the
    /// current sense, on the board's side of the leads, reads the duty's sign).
    pub motor_reversed: [bool; NUM_JOINTS],
    /// The encoder's channels A and B swapped: it counts down as its joint moves to +q.
    pub encoder_reversed: [bool; NUM_JOINTS],
    /// Two encoders' cables swapped: each counter reads the other joint's encoder.
    pub encoders_swapped: Option<(usize, usize)>,
    /// The encoder's counts per joint unit over the drawing's (a gear ratio off: 1.1 is
    /// 10 % more motor turns per joint unit).
    pub count_scale: [f64; NUM_JOINTS],
    /// A normally open home switch where the firmware expects a normally closed one: it
    /// reads actuated away from its switch point and released at it.
    pub switch_normally_open: [bool; NUM_JOINTS],
    /// The brake inverted (a power-to-engage brake, or its coil's output inverted): it
    /// holds when the board releases it and releases when the board applies it.
    pub brake_inverted: [bool; NUM_JOINTS],
}

impl Wiring {
    /// The straight wiring.
    pub fn straight() -> Self {
        Wiring {
            count_scale: [1.0; NUM_JOINTS],
            ..Wiring::default()
        }
    }

    /// Any miswiring at all.
    pub fn is_straight(&self) -> bool {
        *self == Wiring::straight()
    }
}

/// Which hard stop a joint stands at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtStop {
    /// The lower (-q) stop.
    Lower,
    /// The upper (+q) stop.
    Upper,
}

/// The plant with the board and the robot's mechanics around it: what the MCU drives (the
/// driver enable, the brakes' two coil groups, the six duties), what it reads (counters,
/// currents, switches, supply, nFAULT, the e-stop button and the relay's feedback), the
/// hard-wired safety chain between the two, and the switches and hard stops on the joints.
///
/// Every output reaches the plant when the MCU writes it (the hardware traits), through
/// the safety relay: open, it removes the drivers' power (the bridges coast) and the brake
/// coils' power (the springs apply the brakes), whatever the MCU drives.
#[derive(Clone, Debug)]
pub struct BoardOnPlant {
    /// The plant.
    pub plant: Plant,
    /// The MCU's driver enable output (high: the bridges may drive).
    pub enabled: bool,
    /// The MCU's brake output of the legs' group (high: coils powered, released). The
    /// hardware traits switch both groups together.
    pub brakes_released: bool,
    /// The MCU's brake output of the links' group.
    pub link_brakes_released: bool,
    /// The e-stop button is pressed (its contacts open).
    pub estop: bool,
    /// The safety relay's contacts are welded: it stays closed with the button pressed.
    pub relay_welded: bool,
    /// The safety relay is open without the button (a failed coil, a cut wire).
    pub relay_stuck_open: bool,
    /// Each joint's switch is actuated at and below this position.
    pub switch_below: [Option<f64>; NUM_JOINTS],
    /// A switch forced to a level (a failed switch or a cut wire), whatever the joint does.
    pub switch_forced: [Option<bool>; NUM_JOINTS],
    /// Each joint's lower hard stop.
    pub stop_below: [Option<f64>; NUM_JOINTS],
    /// Each joint's upper hard stop.
    pub stop_above: [Option<f64>; NUM_JOINTS],
    /// A current-sense offset added to the readings, A (a failed amplifier).
    pub current_offset_a: [f64; NUM_JOINTS],
    /// Counts added to each encoder's reading (a braked motor settled a count away,
    /// within its brake's play).
    pub count_offset: [i16; NUM_JOINTS],
    /// The board reads the second position channel (the plant's absolute position
    /// sensors, `plant::position_sensor`): a board with the channel fitted.
    pub position_channel: bool,
    /// The channel's read fails (a bus error): the board answers no readings.
    pub position_channel_failed: bool,
    /// How many times the MCU disabled the outputs ([`MotorOutputs::disable`]).
    pub disables: u32,
    /// Plant steps each joint stood at a stop.
    pub steps_at_stop: [u64; NUM_JOINTS],
    /// How the robot is wired to the board ([`Wiring::straight`] unless a test miswires it).
    pub wiring: Wiring,
    /// The plant's encoder counts as last read, and each counter's count as wired (the
    /// scale of [`Wiring::count_scale`] accumulates on them).
    wired: Option<([u16; NUM_JOINTS], [f64; NUM_JOINTS])>,
    at_stop: [Option<AtStop>; NUM_JOINTS],
    last_counts: [u16; NUM_JOINTS],
}

impl BoardOnPlant {
    /// The board around `plant` as at power-up: drivers off, brakes applied, the relay
    /// closed, no switch and no stop (see [`BoardOnPlant::with_layout`]). The plant's
    /// bridges and brakes follow at once (the brakes after their engage time).
    pub fn new(plant: Plant) -> Self {
        let last_counts = plant.encoder_counts();
        let mut b = BoardOnPlant {
            plant,
            enabled: false,
            brakes_released: false,
            link_brakes_released: false,
            estop: false,
            relay_welded: false,
            relay_stuck_open: false,
            switch_below: [None; NUM_JOINTS],
            switch_forced: [None; NUM_JOINTS],
            stop_below: [None; NUM_JOINTS],
            stop_above: [None; NUM_JOINTS],
            current_offset_a: [0.0; NUM_JOINTS],
            count_offset: [0; NUM_JOINTS],
            position_channel: false,
            position_channel_failed: false,
            disables: 0,
            steps_at_stop: [0; NUM_JOINTS],
            wiring: Wiring::straight(),
            wired: None,
            at_stop: [None; NUM_JOINTS],
            last_counts,
        };
        b.apply();
        b
    }

    /// The board around `plant` with its joints resting at `q`, powered up long ago: the
    /// drivers off, the spring-applied brakes holding already (applied and engaged, their
    /// engage time run out unloaded before the joints are placed).
    pub fn at_rest(plant: Plant, q: [f64; NUM_JOINTS]) -> Result<Self, PlantError> {
        let mut b = BoardOnPlant::new(plant);
        b.plant.set_joint_positions(q)?;
        b.plant.advance(0.05, STEP_S)?;
        b.plant.set_joint_positions(q)?;
        b.last_counts = b.plant.encoder_counts();
        Ok(b)
    }

    /// With the switches and stops of `layout`.
    pub fn with_layout(mut self, layout: &Layout) -> Self {
        self.set_layout(layout);
        self
    }

    /// Puts the switches and stops where `layout` says.
    pub fn set_layout(&mut self, layout: &Layout) {
        self.switch_below = layout.switch_below;
        self.stop_below = layout.stop_below;
        self.stop_above = layout.stop_above;
    }

    /// The safety relay is open: the button pressed (unless its contacts are welded), or
    /// failed open.
    pub fn relay_open(&self) -> bool {
        (self.estop && !self.relay_welded) || self.relay_stuck_open
    }

    /// Presses (or releases) the e-stop button: the relay opens at once, removing the
    /// drivers' and the brakes' power. What the MCU does about it (its interrupt) is the
    /// MCU's: [`SafeOutputs::force_safe`].
    pub fn press_estop(&mut self, pressed: bool) {
        self.estop = pressed;
        self.apply();
    }

    /// Joints standing at a stop.
    pub fn at_stop(&self) -> [Option<AtStop>; NUM_JOINTS] {
        self.at_stop
    }

    /// The counters as the MCU last read them.
    pub fn last_counts(&self) -> [u16; NUM_JOINTS] {
        self.last_counts
    }

    /// The switches as wired: forced, or actuated at and below their position.
    pub fn switch_levels(&self) -> [bool; NUM_JOINTS] {
        let q = self.plant.joint_positions();
        std::array::from_fn(|j| {
            self.switch_forced[j].unwrap_or_else(|| {
                self.switch_below[j].is_some_and(|s| q[j] <= s)
                    != self.wiring.switch_normally_open[j]
            })
        })
    }

    /// The counters as wired: the plant's encoders with their counts scaled, reversed and
    /// swapped as [`BoardOnPlant::wiring`] says (the straight wiring reads the plant's).
    fn wired_counts(&mut self) -> [u16; NUM_JOINTS] {
        let plant = self.plant.encoder_counts();
        let w = self.wiring;
        if w.is_straight() {
            self.wired = None;
            return plant;
        }
        let (last, mut acc) = self.wired.unwrap_or((plant, plant.map(f64::from)));
        for j in 0..NUM_JOINTS {
            let delta = f64::from(plant[j].wrapping_sub(last[j]) as i16);
            acc[j] += delta * w.count_scale[j];
        }
        self.wired = Some((plant, acc));
        let mut c: [u16; NUM_JOINTS] = std::array::from_fn(|j| {
            let n = (acc[j].round() as i64).rem_euclid(65536) as u16;
            if w.encoder_reversed[j] {
                n.wrapping_neg()
            } else {
                n
            }
        });
        if let Some((a, b)) = w.encoders_swapped {
            if a < NUM_JOINTS && b < NUM_JOINTS {
                c.swap(a, b);
            }
        }
        c
    }

    /// The counters as the MCU reads them now: the plant's encoders as wired
    /// ([`BoardOnPlant::wiring`]), with [`BoardOnPlant::count_offset`] added (what
    /// [`QuadratureCounter::counts`] answers; a board's emulator reads them at its pins).
    pub fn read_counts(&mut self) -> [u16; NUM_JOINTS] {
        let mut c = self.wired_counts();
        for (c, o) in c.iter_mut().zip(self.count_offset) {
            *c = c.wrapping_add_signed(o);
        }
        self.last_counts = c;
        c
    }

    /// The motor currents as the board's sense amplifiers read them (what
    /// [`CurrentSense::currents`] answers): the amplifier sits on the board's side of the
    /// motor's leads, so it reads the board's duty sign whichever way the leads go, plus
    /// [`BoardOnPlant::current_offset_a`].
    pub fn sensed_currents(&self) -> [f64; NUM_JOINTS] {
        let i = self.plant.currents();
        let reversed = self.wiring.motor_reversed;
        std::array::from_fn(|j| (if reversed[j] { -i[j] } else { i[j] }) + self.current_offset_a[j])
    }

    /// What the MCU drives and the safety chain allows, to the plant: the bridges' enable
    /// and each brake group's coils.
    fn apply(&mut self) {
        let powered = !self.relay_open();
        self.plant.set_bridges_enabled(self.enabled && powered);
        let legs = self.brakes_released && powered;
        let links = self.link_brakes_released && powered;
        let inverted = self.wiring.brake_inverted;
        self.plant.set_brakes_released(std::array::from_fn(|j| {
            (if j < 3 { legs } else { links }) != inverted[j]
        }));
    }

    /// One plant step of `dt` s with the hard stops: a load side driven into a stop (at or
    /// beyond it, its duty not pulling it away) is held there (`load_seized`: the motor
    /// runs through the backlash onto it and stalls); it is free again from the step its duty pulls it away with an effort
    /// through the transmission that overcomes the external load pressing it in (a link
    /// the tool's weight holds on its stop stays there while the drive cannot lift it).
    pub fn step(&mut self, dt: f64) -> Result<(), PlantError> {
        self.apply();
        let duty = self.plant.duty();
        for (j, d) in duty.iter().enumerate() {
            // The net effort on the load side towards +q: what the transmission carries
            // (the motor's drive while it pushes on the seized load, nothing while it
            // crosses the backlash) and the external load.
            let net = self
                .plant
                .joint(j)
                .map_or(0.0, |jt| jt.transmitted_effort() + jt.external_load());
            let away = match self.at_stop[j] {
                Some(AtStop::Lower) => *d > 0.0 && net > 0.0,
                Some(AtStop::Upper) => *d < 0.0 && net < 0.0,
                None => false,
            };
            if away {
                self.at_stop[j] = None;
                self.set_seized(j, false)?;
            }
        }
        self.plant.step(dt)?;
        let q = self.plant.joint_positions();
        for j in 0..NUM_JOINTS {
            if self.at_stop[j].is_none() {
                if self.stop_below[j].is_some_and(|s| q[j] <= s) && duty[j] <= 0.0 {
                    self.at_stop[j] = Some(AtStop::Lower);
                } else if self.stop_above[j].is_some_and(|s| q[j] >= s) && duty[j] >= 0.0 {
                    self.at_stop[j] = Some(AtStop::Upper);
                }
                if self.at_stop[j].is_some() {
                    self.set_seized(j, true)?;
                }
            }
            if self.at_stop[j].is_some() {
                self.steps_at_stop[j] += 1;
            }
        }
        Ok(())
    }

    /// One millisecond: ten steps of [`STEP_S`]. Nothing in it can be refused: the step
    /// is valid, and the faults the stops change are the plant's own, valid already.
    pub fn step_ms(&mut self) {
        for _ in 0..10 {
            let _ = self.step(STEP_S);
        }
    }

    /// The load side of joint `j` held by its stop (or freed), the joint's other faults
    /// kept.
    fn set_seized(&mut self, j: usize, seized: bool) -> Result<(), PlantError> {
        let mut f = self.plant.faults(j)?;
        if f.load_seized != seized {
            f.load_seized = seized;
            self.plant.set_faults(j, f)?;
        }
        Ok(())
    }

    /// A joint's driver reports a fault of its own (over-temperature, under-voltage
    /// lockout) and keeps its bridge off, or is healthy again; its other faults kept.
    pub fn set_driver_failed(&mut self, j: usize, failed: bool) -> Result<(), PlantError> {
        let mut f = self.plant.faults(j)?;
        if f.driver_failed != failed {
            f.driver_failed = failed;
            self.plant.set_faults(j, f)?;
        }
        Ok(())
    }

    /// The pin-level outputs at once (a board's emulator reads them off the pins): the
    /// driver enable, the two brake groups `[legs, links]` and the signed duties.
    pub fn set_outputs(
        &mut self,
        driver_enable: bool,
        brakes: [bool; 2],
        duty: &[f64; NUM_JOINTS],
    ) {
        self.enabled = driver_enable;
        [self.brakes_released, self.link_brakes_released] = brakes;
        self.apply();
        self.set_duties(duty);
    }
}

impl QuadratureCounter for BoardOnPlant {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        self.read_counts()
    }
}

impl AbsolutePositions for BoardOnPlant {
    fn absolute_fitted(&self) -> bool {
        self.position_channel
    }
    /// The plant's absolute position sensors as the board's converter reads them, where
    /// the board has the channel fitted and its read does not fail.
    fn absolute_counts(&mut self) -> Option<[u16; NUM_JOINTS]> {
        (self.position_channel && !self.position_channel_failed)
            .then(|| self.plant.position_sensor_counts())
    }
}

impl MotorOutputs<f64> for BoardOnPlant {
    /// The duties reach the bridges while the driver enable is high, clamped to [-1, 1]
    /// (a non-finite duty drives nothing); with it low, nothing.
    fn set_duties(&mut self, duty: &[f64; NUM_JOINTS]) {
        let d = if self.enabled {
            duty.map(|x| {
                if x.is_finite() {
                    x.clamp(-1.0, 1.0)
                } else {
                    0.0
                }
            })
        } else {
            [0.0; NUM_JOINTS]
        };
        let reversed = self.wiring.motor_reversed;
        let d: [f64; NUM_JOINTS] = std::array::from_fn(|j| if reversed[j] { -d[j] } else { d[j] });
        // Finite duties in [-1, 1]: the plant accepts them.
        let _ = self.plant.set_duty(d);
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.disables += 1;
        let _ = self.plant.set_duty([0.0; NUM_JOINTS]);
        self.apply();
    }
    fn enable(&mut self) {
        self.enabled = true;
        self.apply();
    }
}

impl SafeOutputs for BoardOnPlant {
    /// The e-stop interrupt's register writes: PWM off, driver enable low, brakes applied.
    fn force_safe(&mut self) {
        self.enabled = false;
        self.brakes_released = false;
        self.link_brakes_released = false;
        let _ = self.plant.set_duty([0.0; NUM_JOINTS]);
        self.apply();
    }
}

impl Brakes for BoardOnPlant {
    fn set_brakes_released(&mut self, released: bool) {
        self.brakes_released = released;
        self.link_brakes_released = released;
        self.apply();
    }
}

impl PowerStage<f64> for BoardOnPlant {
    fn supply_voltage(&mut self) -> f64 {
        self.plant.supply_voltage()
    }
    fn driver_fault(&mut self) -> bool {
        self.plant.driver_fault()
    }
}

impl SafetyChain for BoardOnPlant {
    fn estop_pressed(&mut self) -> bool {
        self.estop
    }
    fn relay_open(&mut self) -> bool {
        BoardOnPlant::relay_open(self)
    }
}

impl LimitSwitches for BoardOnPlant {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        self.switch_levels()
    }
}

impl CurrentSense<f64> for BoardOnPlant {
    fn currents(&mut self) -> [f64; NUM_JOINTS] {
        self.sensed_currents()
    }
}
