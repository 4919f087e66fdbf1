"""Hardware in the loop: Modbus load cell and servo blocks, wall-clock pacing, run records, and
a bench emulator.

    featherstar.hil.blocks     LoadCell, Servo (cosim Block protocol)
    featherstar.hil.pacing     Pacer, run_paced
    featherstar.hil.recorder   Recorder (samples.csv, run.json, fault.json)
    featherstar.hil.emulator   start_emulator, spawn_emulator, Emulator
    featherstar.hil.modbus_server  the emulator's Modbus TCP server (exception codes, pipelining, idle timeout)
    featherstar.hil.plant      Plant protocol, FlatPlatePlant
    featherstar.hil.registers  register maps (hil/maps/*.toml); featherstar.hil.codec their encoding
    featherstar.hil.link       device URLs and shared Modbus links
    featherstar.hil.cli        `featherstar emulate`
"""
