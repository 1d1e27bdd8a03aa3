"""What many test modules share: composed configs, tiny-run settings and trained runs, the commands run as a user
runs them, small models and scenes. Test modules import from here, never from each other."""
