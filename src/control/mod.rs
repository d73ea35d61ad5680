//! Live control: the commands a user gives a running simulation (`command`), the panel's
//! plain-data state that validates them (`state`), timed scripts for headless runs
//! (`script`), scenes rebuilt with a
//! new discretization (`rescene`), the run description stored in recordings (`runspec`) and
//! the driver applying it all to a running simulation (`driver`). Nothing here knows egui;
//! the solver core knows nothing of this module.

pub mod checkpoint;
pub mod command;
pub mod driver;
pub mod rescene;
pub mod runspec;
pub mod script;
pub mod state;
pub mod worker;

pub use command::{Command, DtValue};
pub use driver::Driver;
pub use state::{ControlState, Effect};
