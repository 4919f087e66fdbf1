"""Hardware in the loop: Modbus load cell and servo blocks, wall-clock pacing, run records, and
a bench emulator.

    hil.blocks     LoadCell, Servo (cosim Block protocol)
    hil.pacing     Pacer, run_paced
    hil.recorder   Recorder (samples.csv, run.json, fault.json)
    hil.emulator   start_emulator, spawn_emulator, Emulator
    hil.modbus_server  the emulator's Modbus TCP server (exception codes, pipelining, idle timeout)
    hil.plant      Plant protocol, FlatPlatePlant
    hil.registers  register maps (hil/maps/*.toml); hil.codec their encoding
    hil.link       device URLs and shared Modbus links
    hil.cli        `featherstar emulate`
"""
