"""pipegen's pytest plugin (registered through the ``pytest11`` entry point): placeholder until
the plugin lands; importing it costs nothing."""
