"""The BASIC Stamp II program image and its download protocol (`pac-host flash`)."""
