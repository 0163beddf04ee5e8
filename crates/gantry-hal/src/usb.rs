//! USB device discovery through `rusb` (feature `usb`).

use crate::config::UsbDeviceSpec;
use crate::error::{DeviceKind, HalError, HalResult};
use serde::{Deserialize, Serialize};

/// One USB device seen on the bus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct UsbDevice {
    /// Bus number.
    pub bus: u8,
    /// Device address on the bus.
    pub address: u8,
    /// Vendor id.
    pub vendor_id: u16,
    /// Product id.
    pub product_id: u16,
}

/// Lists the USB devices on all buses. A system without USB access (no libusb context, no
/// `/dev/bus/usb`) gives [`HalError::DeviceAbsent`] naming the USB subsystem.
pub fn list_devices() -> HalResult<Vec<UsbDevice>> {
    let devices = rusb::devices().map_err(|e| HalError::DeviceAbsent {
        device: DeviceKind::Usb,
        name: "USB subsystem".into(),
        detail: e.to_string(),
    })?;
    let mut out = Vec::new();
    for d in devices.iter() {
        match d.device_descriptor() {
            Ok(desc) => out.push(UsbDevice {
                bus: d.bus_number(),
                address: d.address(),
                vendor_id: desc.vendor_id(),
                product_id: desc.product_id(),
            }),
            Err(e) => tracing::debug!("USB device {}:{}: {e}", d.bus_number(), d.address()),
        }
    }
    Ok(out)
}

/// Checks `wanted` against the devices present; the first one missing is
/// [`HalError::DeviceAbsent`] with its name and ids.
pub fn require_in(present: &[UsbDevice], wanted: &[UsbDeviceSpec]) -> HalResult<()> {
    for w in wanted {
        if !present
            .iter()
            .any(|d| d.vendor_id == w.vendor_id && d.product_id == w.product_id)
        {
            return Err(HalError::DeviceAbsent {
                device: DeviceKind::Usb,
                name: format!("{} ({:04x}:{:04x})", w.name, w.vendor_id, w.product_id),
                detail: format!("not among the {} USB devices present", present.len()),
            });
        }
    }
    Ok(())
}

/// Lists the bus and checks that every device of `wanted` is there.
pub fn require_all(wanted: &[UsbDeviceSpec]) -> HalResult<()> {
    require_in(&list_devices()?, wanted)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_device_is_named() {
        let present = vec![UsbDevice {
            bus: 1,
            address: 2,
            vendor_id: 0x1a86,
            product_id: 0x7523,
        }];
        let ok = UsbDeviceSpec {
            name: "GRBL".into(),
            vendor_id: 0x1a86,
            product_id: 0x7523,
        };
        require_in(&present, std::slice::from_ref(&ok)).unwrap();
        let camera = UsbDeviceSpec {
            name: "Retiga 1300".into(),
            vendor_id: 0x1234,
            product_id: 0xabcd,
        };
        let e = require_in(&present, &[ok, camera]).unwrap_err();
        assert!(e.to_string().contains("Retiga 1300 (1234:abcd)"), "{e}");
    }

    #[test]
    fn listing_the_bus_returns_or_fails_typed() {
        // In a container there may be no USB bus at all; either way no panic and a typed answer.
        match list_devices() {
            Ok(devs) => {
                // Every listed device is found again by its ids.
                let specs: Vec<UsbDeviceSpec> = devs
                    .iter()
                    .map(|d| UsbDeviceSpec {
                        name: format!("bus {} addr {}", d.bus, d.address),
                        vendor_id: d.vendor_id,
                        product_id: d.product_id,
                    })
                    .collect();
                require_all(&specs).unwrap();
            }
            Err(e) => assert!(matches!(e, HalError::DeviceAbsent { .. })),
        }
    }
}
