"""How the daemon's process runs its users' steps, apart from what a step does."""
