"""facadeforge."""
