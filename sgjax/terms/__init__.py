"""Layer 2, terms: the registry and parser every term shares (``base``), the state queries terms
share (``queries``), episode enders (``enders``) and named term sets (``presets``). The
observation and reward terms are the packages ``sgjax.observations`` and ``sgjax.rewards``."""
