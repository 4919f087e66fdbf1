"""The Block protocol and the runtime units the master drives (Drake's systems/framework, in small):
what a block is, whatever runs it."""
