//! Where a simulated flight controller is: the flight it flies ([`Flight`]: a circle, or a
//! [`Route`] from home and back), its position and velocity at a time ([`Kinematics`]), and
//! what its telemetry says of them (latitude and longitude, heading, height). One model for
//! every simulated autopilot, so PX4 and ArduPilot fly the same flight to the last bit.

use mavlora::dialect::GLOBAL_POSITION_INT_DATA;
use mavlora::{Duration, Instant};

/// Where the simulated flight controller flies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Flight {
    /// A 200 m circle at 10 m/s, 50 m up, for ever.
    Circle,
    /// A route, then landed at home.
    Route(Route),
}

/// An out-and-back route from home: climb, fly `length_m` (half out along `bearing_deg`, half
/// back) at `speed_m_s`, descend.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Route {
    /// Horizontal distance flown, m.
    pub length_m: f64,
    /// Cruise speed, m/s.
    pub speed_m_s: f64,
    /// Cruise height above home, m.
    pub altitude_m: f64,
    /// Climb rate, m/s.
    pub climb_m_s: f64,
    /// Descent rate, m/s.
    pub descent_m_s: f64,
    /// Direction of the outbound leg, degrees from north.
    pub bearing_deg: f64,
}

/// Position and velocity in metres and m/s, north-east-up from home.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Kinematics {
    /// North of home, m.
    pub north: f64,
    /// East of home, m.
    pub east: f64,
    /// Above home, m.
    pub up: f64,
    /// Velocity north, m/s.
    pub vn: f64,
    /// Velocity east, m/s.
    pub ve: f64,
    /// Velocity up, m/s.
    pub vu: f64,
}

impl Route {
    /// The paper's route (section VI-A): 4 km at 10 m/s at 100 m. Climb at 3 m/s and descent
    /// at 1.25 m/s (PX4's `MPC_Z_VEL_MAX_UP` default and a gentle landing) make the flight
    /// 513.3 s, the paper's 513 s wired flight.
    pub const PAPER: Route = Route {
        length_m: 4000.0,
        speed_m_s: 10.0,
        altitude_m: 100.0,
        climb_m_s: 3.0,
        descent_m_s: 1.25,
        bearing_deg: 45.0,
    };

    fn phases(&self) -> (f64, f64, f64) {
        (
            self.altitude_m / self.climb_m_s,
            self.length_m / self.speed_m_s,
            self.altitude_m / self.descent_m_s,
        )
    }

    /// Take-off to touch-down.
    pub fn duration(&self) -> Duration {
        let (c, f, d) = self.phases();
        Duration::from_secs_f64(c + f + d)
    }

    /// Where the vehicle is `t` seconds after take-off (on the ground at home after landing).
    pub fn at(&self, t: f64) -> Kinematics {
        let (climb, cruise, descent) = self.phases();
        let (sin, cos) = self.bearing_deg.to_radians().sin_cos();
        let half = self.length_m / 2.0;
        let t = t.max(0.0);
        if t < climb {
            return Kinematics {
                up: self.climb_m_s * t,
                vu: self.climb_m_s,
                ..Kinematics::default()
            };
        }
        if t < climb + cruise {
            let flown = (t - climb) * self.speed_m_s;
            let (out, dir) = if flown < half {
                (flown, 1.0)
            } else {
                (self.length_m - flown, -1.0)
            };
            return Kinematics {
                north: out * cos,
                east: out * sin,
                up: self.altitude_m,
                vn: dir * self.speed_m_s * cos,
                ve: dir * self.speed_m_s * sin,
                vu: 0.0,
            };
        }
        let down = t - climb - cruise;
        if down < descent {
            return Kinematics {
                up: self.altitude_m - self.descent_m_s * down,
                vu: -self.descent_m_s,
                ..Kinematics::default()
            };
        }
        Kinematics::default()
    }
}

impl Flight {
    /// Position and velocity `secs` seconds after boot.
    pub fn at(&self, secs: f64) -> Kinematics {
        match self {
            Flight::Circle => {
                let w = 10.0 / 200.0;
                Kinematics {
                    north: 200.0 * (w * secs).cos(),
                    east: 200.0 * (w * secs).sin(),
                    up: 50.0,
                    vn: -10.0 * (w * secs).sin(),
                    ve: 10.0 * (w * secs).cos(),
                    vu: 0.0,
                }
            }
            Flight::Route(r) => r.at(secs),
        }
    }

    /// Position and velocity at `now` of an autopilot that booted (and started flying) at
    /// `booted`.
    pub fn since_boot(&self, booted: Instant, now: Instant) -> Kinematics {
        self.at(now.saturating_duration_since(booted).as_secs_f64())
    }
}

/// Home, near Odense (the paper's test area), in 1e-7 degrees.
const HOME_LAT: i32 = 553_700_000;
const HOME_LON: i32 = 103_900_000;
/// Metres per 1e-7 degree of latitude, and of longitude at home's latitude.
const M_PER_LAT: f64 = 0.011_132;
const M_PER_LON: f64 = 0.011_132 * 0.5664;

impl Kinematics {
    /// Latitude and longitude, 1e-7 degrees.
    pub fn lat_lon(&self) -> (i32, i32) {
        (
            HOME_LAT + (self.north / M_PER_LAT) as i32,
            HOME_LON + (self.east / M_PER_LON) as i32,
        )
    }

    /// Height above home, mm.
    pub fn rel_alt_mm(&self) -> i32 {
        (self.up * 1000.0) as i32
    }

    /// `GLOBAL_POSITION_INT` at `time_boot_ms`, heading `hdg` (centidegrees, as
    /// [`heading_cdeg`](Self::heading_cdeg) gives it); home is 10 m above sea level.
    pub fn global_position_int(&self, time_boot_ms: u32, hdg: u16) -> GLOBAL_POSITION_INT_DATA {
        let (lat, lon) = self.lat_lon();
        let rel_mm = self.rel_alt_mm();
        GLOBAL_POSITION_INT_DATA {
            time_boot_ms,
            lat,
            lon,
            alt: 10_000 + rel_mm,
            relative_alt: rel_mm,
            vx: (self.vn * 100.0) as i16,
            vy: (self.ve * 100.0) as i16,
            vz: (-self.vu * 100.0) as i16,
            hdg,
        }
    }

    /// Heading over ground in centidegrees (0..36000); `hovering_deg` while the vehicle
    /// barely moves (under 0.1 m/s), where the velocity says nothing of it.
    pub fn heading_cdeg(&self, hovering_deg: f64) -> u16 {
        let course = if self.vn.hypot(self.ve) < 0.1 {
            hovering_deg
        } else {
            self.ve.atan2(self.vn).to_degrees()
        };
        ((course + 360.0) % 360.0 * 100.0) as u16
    }
}
