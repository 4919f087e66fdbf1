"""Hardware in the loop: Modbus load cell and servo blocks, wall-clock pacing, run records, and
a bench emulator.

    featherstar.hil.blocks     LoadCell, Servo (cosim Block protocol)
    featherstar.hil.pacing     Pacer, run_paced
    featherstar.hil.recorder   Recorder (samples.csv, run.json, fault.json)
    featherstar.hil.emulator   start_emulator, spawn_emulator, serve
    featherstar.hil.emulated_bench  Emulator: the devices' register-level behaviour
    featherstar.hil.lifecycle  boot session, command watchdog, rest (emulated firmware)
    featherstar.hil.session    the client's check of a device's boot id and uptime
    featherstar.hil.timed_registers, timed_device, timed_emulation, timed_io, timed_run
                               device-timed runs: registers, emulated firmware, the PC's side
    featherstar.hil.modbus_server  the emulator's Modbus TCP server (exception codes, pipelining, idle timeout)
    featherstar.hil.plant      Plant protocol, FlatPlatePlant
    featherstar.hil.registers  register maps (hil/maps/*.toml; map_reader: typed access);
                               featherstar.hil.codec their encoding
    featherstar.hil.link       device URLs and shared Modbus links
    featherstar.hil.cli        `featherstar emulate`
"""
