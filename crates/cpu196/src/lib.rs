//! CPU196 controller board: PC protocol codec, kernel + PIC model, host client.
