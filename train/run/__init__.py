"""The run machinery: checkpoints, environments spread over devices, sweeps over several
processes, sweep space files and SocialGym 2.0 experiment config conversion."""
