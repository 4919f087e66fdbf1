"""FMI: an FMU's variables and types read before its binary loads (fmu_info, fmi_types), archive
checks, and the one adapter through which every fmpy call goes (fmu_block)."""
