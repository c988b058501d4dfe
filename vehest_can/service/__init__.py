"""The ECU as a service: the daemon on a bus, hardware-in-the-loop rehearsal, systemd notify, log replay."""
